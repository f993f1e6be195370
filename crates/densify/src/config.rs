//! Configuration: the 3DGS schedule and thresholds, and the switches of every policy.
//!
//! Defaults follow the original 3DGS code (graphdeco-inria/gaussian-splatting, `train.py`,
//! `arguments/__init__.py`, `scene/gaussian_model.py`): `densify_from_iter = 500`,
//! `densify_until_iter = 15000`, `densification_interval = 100`, `opacity_reset_interval = 3000`,
//! `densify_grad_threshold = 0.0002`, `percent_dense = 0.01`, minimum opacity 0.005, screen size
//! 20 px, world size `0.1 · extent`, split into `N = 2` children of scale `s / (0.8 N)`.
//!
//! With the `serde` feature a [`DensifyConfig`] is written as one flat object: the schedule's
//! four iteration counts, the thresholds, and every other field only where it differs from its
//! default (so a file that predates a field reads as the default).

use crate::error::DensifyError;

/// When statistics are accumulated, when densification runs and when opacities are reset.
///
/// Iterations count from 1, as in 3DGS's `train.py`. The conditions are 3DGS's exactly:
/// - statistics accumulate while `iteration < until`;
/// - densify-and-prune runs when `iteration < until && iteration > from && iteration % interval == 0`;
/// - the screen-size and world-size prune applies when `iteration > opacity_reset_interval`;
/// - opacity is reset when `iteration < until` and either `iteration % opacity_reset_interval == 0`
///   or (white background) `iteration == from`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Schedule {
    /// `densify_from_iter` (default 500); densification starts strictly after it.
    pub from: u64,
    /// `densify_until_iter` (default 15000), exclusive.
    pub until: u64,
    /// `densification_interval` (default 100).
    pub interval: u64,
    /// `opacity_reset_interval` (default 3000).
    pub opacity_reset_interval: u64,
    /// The scene is trained on a white background (D-NeRF synthetic): 3DGS then also resets
    /// opacity at `iteration == from`. Recorded only when set.
    #[cfg_attr(feature = "serde", serde(default, skip_serializing_if = "is_false"))]
    pub white_background: bool,
}

impl Default for Schedule {
    fn default() -> Self {
        Self {
            from: 500,
            until: 15000,
            interval: 100,
            opacity_reset_interval: 3000,
            white_background: false,
        }
    }
}

impl Schedule {
    /// Whether statistics are accumulated at `iteration`.
    pub fn accumulates(&self, iteration: u64) -> bool {
        iteration < self.until
    }

    /// Whether densify-and-prune runs at `iteration`.
    pub fn densifies(&self, iteration: u64) -> bool {
        iteration < self.until && iteration > self.from && iteration.is_multiple_of(self.interval)
    }

    /// Whether the screen-size and world-size prune applies at `iteration` (after the first
    /// opacity reset).
    pub fn prunes_large(&self, iteration: u64) -> bool {
        iteration > self.opacity_reset_interval
    }

    /// Whether opacities are reset at `iteration`.
    pub fn resets_opacity(&self, iteration: u64) -> bool {
        iteration < self.until
            && iteration > 0
            && (iteration.is_multiple_of(self.opacity_reset_interval)
                || (self.white_background && iteration == self.from))
    }

    /// Whether anything happens at `iteration` (a plan other than the identity may result).
    pub fn acts(&self, iteration: u64) -> bool {
        self.densifies(iteration) || self.resets_opacity(iteration)
    }
}

/// EvoGS's uncertainty-aware trigger: densify only where, besides the gradient criterion, the
/// mean residual norm over the interval is below `tau_r` and the mean angular deviation is
/// below `tau_theta`.
///
/// The paper fixes both across scenes but prints no values. Our defaults:
/// - `tau_r = 0.01`: the residual `|z - d̂|` of the position part, divided by the scene extent
///   (per step). 0.01 · extent is 3DGS's own boundary between "small" and "large" Gaussians
///   (`percent_dense`): a prior that misplaces a Gaussian by more than the footprint of a small
///   Gaussian is not trusted to seed new ones.
/// - `tau_theta = π/3`: θ is 0 for consistent motion and averages π/2 for directions drawn at
///   random; π/3 blocks Gaussians whose motion is closer to random than to consistent.
///
/// A Gaussian with no residual (or θ) sample in the interval (too little history) passes that
/// test: there is no evidence of instability.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Trigger {
    /// τ_r, relative to the scene extent.
    pub tau_r: f32,
    /// τ_θ, radians.
    pub tau_theta: f32,
}

impl Default for Trigger {
    fn default() -> Self {
        Self {
            tau_r: 0.01,
            tau_theta: std::f32::consts::FRAC_PI_3,
        }
    }
}

/// Every threshold and every policy switch. Each policy is switchable on its own, so every
/// combination of the ablation table can be expressed.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DensifyConfig {
    /// When it acts (written flat, beside the thresholds).
    #[cfg_attr(feature = "serde", serde(flatten))]
    pub schedule: Schedule,
    /// Clone small Gaussians with a large gradient (3DGS).
    #[cfg_attr(
        feature = "serde",
        serde(default = "yes", skip_serializing_if = "is_true")
    )]
    pub clone: bool,
    /// Split large Gaussians with a large gradient (3DGS).
    #[cfg_attr(
        feature = "serde",
        serde(default = "yes", skip_serializing_if = "is_true")
    )]
    pub split: bool,
    /// Prune transparent and (after the first reset) too large Gaussians (3DGS).
    #[cfg_attr(
        feature = "serde",
        serde(default = "yes", skip_serializing_if = "is_true")
    )]
    pub prune: bool,
    /// Reset opacities periodically (3DGS).
    #[cfg_attr(
        feature = "serde",
        serde(default = "yes", skip_serializing_if = "is_true")
    )]
    pub opacity_reset: bool,
    /// EvoGS's uncertainty-aware trigger, when `Some`.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub trigger: Option<Trigger>,
    /// EvoGS's deformation-aware clone/split with this α (paper: 0.5), when `Some`.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub deformation_alpha: Option<f32>,
    /// Mean NDC gradient norm at or above which a Gaussian is densified (0.0002).
    pub grad_threshold: f32,
    /// Max scale at or below `percent_dense · extent` clones, above splits (0.01).
    pub percent_dense: f32,
    /// Opacity below which a Gaussian is pruned (0.005).
    pub min_opacity: f32,
    /// Screen radius (px) above which a Gaussian is pruned after the first opacity reset, when
    /// `Some` (the 3DGS paper's 20); `None` (the default): no screen-size prune.
    ///
    /// `None` is what 3DGS's and Deformable-3D-Gaussians' code do: `densification_postfix`
    /// zeroes `max_radii2D` just before `densify_and_prune` compares it with 20, so the test
    /// never fires and their published figures were made without it. With it, EvoGS collapsed on
    /// D-NeRF jumpingjacks at 400×400 (3 517 Gaussians at the first reset, 133 from 450
    /// iterations later): its trigger keeps large Gaussians from splitting, so they stay above
    /// 20 px and are pruned in turn, and each prune leaves the survivors larger. Run configs
    /// written before this was optional hold `20.0`, which reads back as `Some(20.0)`.
    pub max_screen_radius: Option<f32>,
    /// Max scale above `max_world_fraction · extent` is pruned (0.1).
    pub max_world_fraction: f32,
    /// Children per split (2); each gets scale / (0.8 · children).
    #[cfg_attr(
        feature = "serde",
        serde(
            default = "default_split_children",
            skip_serializing_if = "is_default_split_children"
        )
    )]
    pub split_children: usize,
    /// Opacity reset value: opacity becomes min(opacity, this) (0.01).
    #[cfg_attr(
        feature = "serde",
        serde(
            default = "default_reset_opacity",
            skip_serializing_if = "is_default_reset_opacity"
        )
    )]
    pub reset_opacity: f32,
    /// Seed of the split sampling (combined with the iteration).
    #[cfg_attr(feature = "serde", serde(default, skip_serializing_if = "is_zero"))]
    pub seed: u64,
    /// Densification never grows the count past this (brush's `max_splats`): when the clones and
    /// splits a step wants would exceed it, those with the largest mean gradient go first and
    /// the rest wait (counted in [`crate::PlanSummary::capped`]). `None`: no limit.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub max_gaussians: Option<usize>,
}

/// serde's defaults and omissions: a field at its default is not written, and reads back as it.
#[cfg(feature = "serde")]
fn yes() -> bool {
    true
}
#[cfg(feature = "serde")]
fn is_true(v: &bool) -> bool {
    *v
}
#[cfg(feature = "serde")]
fn is_false(v: &bool) -> bool {
    !*v
}
#[cfg(feature = "serde")]
fn is_zero(v: &u64) -> bool {
    *v == 0
}
#[cfg(feature = "serde")]
fn default_split_children() -> usize {
    DensifyConfig::default().split_children
}
#[cfg(feature = "serde")]
fn is_default_split_children(v: &usize) -> bool {
    *v == default_split_children()
}
#[cfg(feature = "serde")]
fn default_reset_opacity() -> f32 {
    DensifyConfig::default().reset_opacity
}
#[cfg(feature = "serde")]
fn is_default_reset_opacity(v: &f32) -> bool {
    *v == default_reset_opacity()
}

impl Default for DensifyConfig {
    /// Standard 3DGS adaptive density control, EvoGS policies off.
    fn default() -> Self {
        Self {
            schedule: Schedule::default(),
            clone: true,
            split: true,
            prune: true,
            opacity_reset: true,
            trigger: None,
            deformation_alpha: None,
            grad_threshold: 0.0002,
            percent_dense: 0.01,
            min_opacity: 0.005,
            max_screen_radius: None,
            max_world_fraction: 0.1,
            split_children: 2,
            reset_opacity: 0.01,
            seed: 0,
            max_gaussians: None,
        }
    }
}

impl DensifyConfig {
    /// Standard 3DGS plus both EvoGS policies with the paper's α = 0.5 and our τ defaults.
    pub fn evogs() -> Self {
        Self {
            trigger: Some(Trigger::default()),
            deformation_alpha: Some(0.5),
            ..Self::default()
        }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), DensifyError> {
        let bad = |field: &'static str, value: String, problem: &'static str| {
            Err(DensifyError::Config {
                field,
                value,
                problem,
            })
        };
        let finite_pos = [
            ("grad_threshold", self.grad_threshold),
            ("percent_dense", self.percent_dense),
            ("max_world_fraction", self.max_world_fraction),
        ];
        let screen = self.max_screen_radius.map(|v| ("max_screen_radius", v));
        for (field, v) in finite_pos.into_iter().chain(screen) {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, v.to_string(), "must be finite and positive");
            }
        }
        for (field, v) in [
            ("min_opacity", self.min_opacity),
            ("reset_opacity", self.reset_opacity),
        ] {
            if !(v > 0.0 && v < 1.0) {
                return bad(field, v.to_string(), "must lie in (0, 1)");
            }
        }
        if self.split_children == 0 {
            return bad("split_children", "0".into(), "must be at least 1");
        }
        if self.schedule.interval == 0 {
            return bad("schedule.interval", "0".into(), "must be at least 1");
        }
        if self.schedule.opacity_reset_interval == 0 {
            return bad(
                "schedule.opacity_reset_interval",
                "0".into(),
                "must be at least 1",
            );
        }
        if let Some(t) = self.trigger {
            if !(t.tau_r.is_finite() && t.tau_r > 0.0) {
                return bad(
                    "trigger.tau_r",
                    t.tau_r.to_string(),
                    "must be finite and positive",
                );
            }
            if !(t.tau_theta > 0.0 && t.tau_theta.is_finite()) {
                return bad(
                    "trigger.tau_theta",
                    t.tau_theta.to_string(),
                    "must be finite and positive",
                );
            }
        }
        if let Some(a) = self.deformation_alpha
            && !a.is_finite()
        {
            return bad("deformation_alpha", a.to_string(), "must be finite");
        }
        Ok(())
    }
}
