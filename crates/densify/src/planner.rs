//! Making a plan: 3DGS's densify-and-prune and opacity reset, with EvoGS's trigger and
//! deformation-aware clone/split as switchable policies.
//!
//! The decisions follow `densify_and_prune` of 3DGS (`scene/gaussian_model.py`):
//! 1. mean gradient `g = grad_sum / visible` (0 when never visible);
//! 2. clone where `g >= grad_threshold` and `max scale <= percent_dense · extent`, appending
//!    copies;
//! 3. split where `g >= grad_threshold` and `max scale > percent_dense · extent`: N children
//!    (all first children, then all second children, as `repeat(N, 1)` orders them) at
//!    `mean + R(q) (s ⊙ n)`, `n ~ N(0, I)`, i.e. sampled from N(mean, Σ) in world space, with
//!    scale `s / (0.8 N)`; the parent is removed;
//! 4. prune, over the resulting set, opacity < `min_opacity`, and after the first opacity reset
//!    also max scale > 0.1 · extent, and max screen radius > `max_screen_radius` when that is
//!    set.
//!
//! The screen-size prune is off by default, as in the original code, where
//! `densification_postfix` zeroes `max_radii2D` before the prune of step 4 reads it (see
//! [`DensifyConfig::max_screen_radius`] for why we follow the code, not the paper). When set, it
//! uses the maximum radius accumulated over the interval, as the paper describes (new rows have
//! no screen statistics and are not screen-pruned).
//!
//! EvoGS: the trigger adds `mean residual < τ_r` and `mean θ < τ_θ` to the gradient criterion of
//! both clone and split; deformation-aware densification first moves the source to
//! `canonical + α·d̃` (every enabled component, raw space) and clones or splits from there,
//! leaving a cloned source itself unchanged. Clone/split and prune decisions use the canonical
//! parameters. Without a deformation (e.g. during a static warm-up) d̃ is taken as 0.

use crate::config::DensifyConfig;
use crate::error::DensifyError;
use crate::math::rotation;
use crate::plan::{DensifyPlan, NewValues, PlanSummary, Values};
use crate::stats::DensifyStats;
use glam::Vec3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use splat_core::GaussiansView;
use splat_core::logit;
use splat_core::{Component, Layout, RowPlan};

/// The latest corrected deformation d̃ (N × D, from evo-state's step) and its layout.
#[derive(Debug, Clone, Copy)]
pub struct Deformation<'a> {
    /// d̃, row-major: one row of `layout.dim()` floats per Gaussian.
    pub corrected: &'a [f32],
    /// Which components a row holds, in which columns.
    pub layout: Layout,
}

/// Everything a plan is made from.
#[derive(Debug, Clone, Copy)]
pub struct PlanInput<'a> {
    /// The Gaussians the statistics were gathered on (canonical parameters).
    pub gaussians: GaussiansView<'a>,
    /// The statistics accumulated since the last densification, one row per Gaussian.
    pub stats: &'a DensifyStats,
    /// Scene extent ([`crate::scene_extent`]).
    pub extent: f32,
    /// Training iteration, from 1.
    pub iteration: u64,
    /// Needed only by the deformation-aware policy.
    pub deformation: Option<Deformation<'a>>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Densify {
    No,
    Clone,
    Split,
    Blocked,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Prune {
    No,
    Opacity,
    Screen,
    World,
}

/// Offsets of the deformation components inside the deformation vector.
#[derive(Clone, Copy)]
struct Offsets {
    position: Option<usize>,
    rotation: Option<usize>,
    scale: Option<usize>,
    opacity: Option<usize>,
    colour: Option<usize>,
    dim: usize,
}

impl Offsets {
    fn new(layout: &Layout) -> Self {
        let at = |c| layout.range(c).map(|r| r.start);
        Self {
            position: at(Component::Position),
            rotation: at(Component::Rotation),
            scale: at(Component::Scale),
            opacity: at(Component::Opacity),
            colour: at(Component::Colour),
            dim: layout.dim(),
        }
    }
}

/// Makes the plan for `input.iteration`. Returns the identity plan when the schedule does
/// nothing at that iteration.
pub fn make_plan(
    config: &DensifyConfig,
    input: &PlanInput<'_>,
) -> Result<DensifyPlan, DensifyError> {
    config.validate()?;
    let g = &input.gaussians;
    g.check_lengths().map_err(|e| DensifyError::Input {
        field: "gaussians",
        problem: e.to_string(),
    })?;
    let n = g.len();
    input.stats.check()?;
    if input.stats.len() != n {
        return Err(DensifyError::Length {
            field: "stats",
            expected: n,
            actual: input.stats.len(),
        });
    }
    if !(input.extent.is_finite() && input.extent > 0.0) {
        return Err(DensifyError::Input {
            field: "extent",
            problem: format!("scene extent {} must be finite and positive", input.extent),
        });
    }
    let deformation = match (config.deformation_alpha, input.deformation) {
        (Some(alpha), Some(d)) => {
            let off = Offsets::new(&d.layout);
            if d.corrected.len() != n * off.dim {
                return Err(DensifyError::Length {
                    field: "deformation.corrected",
                    expected: n * off.dim,
                    actual: d.corrected.len(),
                });
            }
            Some((alpha, d.corrected, off))
        }
        _ => None,
    };

    let it = input.iteration;
    let schedule = &config.schedule;
    if !schedule.acts(it) {
        return Ok(DensifyPlan::identity(n));
    }
    let densify = schedule.densifies(it);
    let mut summary = PlanSummary {
        before: n,
        blocked: config.trigger.map(|_| 0),
        ..PlanSummary::default()
    };
    let sh_stride = g.sh_stride();
    let values = |i: usize| -> Values {
        let mut v = Values {
            mean: g.means[i],
            log_scale: g.log_scales[i],
            rotation: g.rotations[i],
            opacity_logit: g.opacity_logits[i],
            sh_dc: [
                g.sh[i * sh_stride],
                g.sh[i * sh_stride + 1],
                g.sh[i * sh_stride + 2],
            ],
        };
        if let Some((alpha, d, off)) = deformation {
            let row = &d[i * off.dim..(i + 1) * off.dim];
            let add = |dst: &mut [f32], start: Option<usize>| {
                if let Some(s) = start {
                    for (k, x) in dst.iter_mut().enumerate() {
                        *x += alpha * row[s + k];
                    }
                }
            };
            add(&mut v.mean, off.position);
            add(&mut v.rotation, off.rotation);
            add(&mut v.log_scale, off.scale);
            add(std::slice::from_mut(&mut v.opacity_logit), off.opacity);
            add(&mut v.sh_dc, off.colour);
        }
        v
    };

    let (kept, parent_from_new, new_values) = if densify {
        let small_limit = config.percent_dense * input.extent;
        let world_limit = config.max_world_fraction * input.extent;
        let prunes_large = schedule.prunes_large(it);
        // Thresholds compared in raw space (monotone activations), which avoids an `exp` per
        // Gaussian: sigmoid(x) < p ⇔ x < logit(p), max exp(l) > s ⇔ max l > ln s.
        let min_logit = logit(config.min_opacity);
        let ln_world = world_limit.ln();
        let ln_small = small_limit.ln();
        let max_log = |l: [f32; 3]| l[0].max(l[1]).max(l[2]);
        let prune_of = |opacity_logit: f32, log_scale: [f32; 3], radius: f32| -> Prune {
            if !config.prune {
                Prune::No
            } else if opacity_logit < min_logit {
                Prune::Opacity
            } else if prunes_large && config.max_screen_radius.is_some_and(|r| radius > r) {
                Prune::Screen
            } else if prunes_large && max_log(log_scale) > ln_world {
                Prune::World
            } else {
                Prune::No
            }
        };
        let stats = input.stats;
        let mut decisions: Vec<(Densify, Prune)> = (0..n)
            .into_par_iter()
            .with_min_len(4096)
            .map(|i| {
                let large_grad = stats.mean_grad(i) >= config.grad_threshold;
                let trusted = config.trigger.is_none_or(|t| {
                    stats.mean_residual(i) < t.tau_r && stats.mean_theta(i) < t.tau_theta
                });
                let small = max_log(g.log_scales[i]) <= ln_small;
                let d = match (large_grad, trusted, small) {
                    (false, _, _) => Densify::No,
                    (true, false, _) => Densify::Blocked,
                    (true, true, true) if config.clone => Densify::Clone,
                    (true, true, false) if config.split => Densify::Split,
                    _ => Densify::No,
                };
                let p = prune_of(g.opacity_logits[i], g.log_scales[i], stats.max_radius[i]);
                (d, p)
            })
            .collect();

        if let Some(max) = config.max_gaussians {
            summary.capped = cap_growth(&mut decisions, stats, max, config.split_children);
        }
        // Only the densified rows' d̃ is read: check those for non-finite values.
        if let Some((_, d, off)) = deformation
            && let Some(i) = (0..n).find(|&i| {
                matches!(decisions[i].0, Densify::Clone | Densify::Split)
                    && d[i * off.dim..(i + 1) * off.dim]
                        .iter()
                        .any(|v| !v.is_finite())
            })
        {
            return Err(DensifyError::Input {
                field: "deformation.corrected",
                problem: format!("non-finite value at Gaussian {i}"),
            });
        }
        let count = |p: Prune, summary: &mut PlanSummary| match p {
            Prune::No => true,
            Prune::Opacity => {
                summary.pruned_opacity += 1;
                false
            }
            Prune::Screen => {
                summary.pruned_screen += 1;
                false
            }
            Prune::World => {
                summary.pruned_world += 1;
                false
            }
        };
        let mut kept = Vec::with_capacity(n);
        for (i, &(d, p)) in decisions.iter().enumerate() {
            match d {
                Densify::Split => summary.split += 1,
                Densify::Clone => summary.cloned += 1,
                Densify::Blocked => *summary.blocked.get_or_insert(0) += 1,
                Densify::No => {}
            }
            if d != Densify::Split && count(p, &mut summary) {
                kept.push(i as u32);
            }
        }
        let new_count = summary.cloned + config.split_children * summary.split;
        let mut parents = Vec::with_capacity(new_count);
        let mut new_values = NewValues::with_capacity(new_count);
        let mut push_new = |parent: usize, v: Values, summary: &mut PlanSummary| {
            if count(prune_of(v.opacity_logit, v.log_scale, 0.0), summary) {
                parents.push(parent as u32);
                new_values.push(&v);
            }
        };
        for (i, &(d, _)) in decisions.iter().enumerate() {
            if d == Densify::Clone {
                push_new(i, values(i), &mut summary);
            }
        }
        let split_rows: Vec<usize> = (0..n)
            .filter(|&i| decisions[i].0 == Densify::Split)
            .collect();
        let children = config.split_children;
        let shrink = (0.8 * children as f32).ln();
        let mut rng =
            ChaCha8Rng::seed_from_u64(config.seed ^ it.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        for _ in 0..children {
            for &i in &split_rows {
                let source = values(i);
                let s = Vec3::from(source.log_scale.map(f32::exp));
                let noise = Vec3::new(
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                );
                let offset = rotation(source.rotation) * (s * noise);
                let child = Values {
                    mean: (Vec3::from(source.mean) + offset).to_array(),
                    log_scale: source.log_scale.map(|l| l - shrink),
                    ..source
                };
                summary.children += 1;
                push_new(i, child, &mut summary);
            }
        }
        (kept, parents, new_values)
    } else {
        ((0..n as u32).collect(), Vec::new(), NewValues::default())
    };

    let rows = RowPlan {
        kept,
        parent_from_new,
    };
    let new_len = rows.new_len();
    let reset_rows = if config.opacity_reset && schedule.resets_opacity(it) {
        (0..new_len as u32).collect()
    } else {
        Vec::new()
    };
    summary.reset = reset_rows.len();
    summary.after = new_len;
    Ok(DensifyPlan {
        rows,
        old_len: n,
        new_values,
        reset_rows,
        reset_opacity: config.reset_opacity,
        clears_stats: densify,
        summary,
    })
}

/// Demotes clones and splits to `Densify::No` so that the rows after the plan (kept rows plus
/// new ones, before the new rows' own prune) do not exceed `max`: candidates are taken by mean
/// gradient, largest first (ties by index), each accepted when it still fits. Returns how many
/// were demoted. Never removes rows: when the rows kept without densifying already exceed
/// `max`, every candidate waits.
fn cap_growth(
    decisions: &mut [(Densify, Prune)],
    stats: &crate::DensifyStats,
    max: usize,
    children: usize,
) -> usize {
    let mut rows = decisions.iter().filter(|d| d.1 == Prune::No).count();
    let mut candidates: Vec<usize> = (0..decisions.len())
        .filter(|&i| matches!(decisions[i].0, Densify::Clone | Densify::Split))
        .collect();
    candidates.sort_by(|&a, &b| {
        stats
            .mean_grad(b)
            .total_cmp(&stats.mean_grad(a))
            .then(a.cmp(&b))
    });
    let mut capped = 0;
    for i in candidates {
        // A clone adds a row; a split replaces its parent (kept unless pruned) by its children.
        let after = match decisions[i].0 {
            Densify::Clone => rows + 1,
            _ => rows + children - usize::from(decisions[i].1 == Prune::No),
        };
        if after <= max {
            rows = after;
        } else {
            decisions[i].0 = Densify::No;
            capped += 1;
        }
    }
    capped
}
