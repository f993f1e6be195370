//! One query's result ([`Step`]): prior, statistics, gain and corrected state, and what the
//! backward pass returns ([`Backward`]).

use rayon::prelude::*;
use splat_core::{Component, Layout};

use crate::error::EvoError;
use crate::frames::History;

/// Motion statistics of one Gaussian (h = 3), on the position part, per frame spacing.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stats {
    /// |v2| = |x_k2 - x_k3| / (k2 - k3).
    pub speed_prev: f32,
    /// |v1| = |x_k1 - x_k2| / (k1 - k2).
    pub speed_last: f32,
    /// θ, the angle between v2 and v1 (0 below the motion floor).
    pub theta: f32,
}

/// The gain of a step.
#[derive(Debug, Clone, PartialEq)]
pub enum Gains {
    /// No correction: d̃ = z (h <= 1, or evolution off).
    Observation,
    /// One K for every Gaussian (warm-up h = 2, or a fixed gain).
    Uniform(f32),
    /// K_i = Ψ(inputs_i).
    Learned(Vec<f32>),
}

impl Gains {
    /// K of Gaussian `i` (1 when d̃ = z).
    pub fn at(&self, i: usize) -> f32 {
        match self {
            Gains::Observation => 1.0,
            Gains::Uniform(k) => *k,
            Gains::Learned(k) => k[i],
        }
    }
}

/// The result of a forward pass at time t. Read-only: committing is a separate call.
#[derive(Debug, Clone)]
pub struct Step {
    pub(crate) time: f32,
    pub(crate) frame: Option<usize>,
    pub(crate) history: History,
    pub(crate) rows: usize,
    pub(crate) generation: u64,
    pub(crate) corrected: Vec<f32>,
    pub(crate) prior: Option<Vec<f32>>,
    pub(crate) gains: Gains,
    pub(crate) stats: Option<Vec<Stats>>,
    pub(crate) psi_cache: Option<tiny_nn::MlpCache>,
    pub(crate) memory_next: Option<Vec<f32>>,
    /// Ψ's normalised inputs (h = 3; otherwise left over from an earlier pass, for reuse).
    pub(crate) scratch: Vec<f32>,
    /// Per-feature mean squares of this step's raw Ψ inputs (h = 3), folded into the running
    /// RMS by a commit.
    pub(crate) input_mean_sq: Option<Vec<f64>>,
    /// s = (t - t_k1)/(t_k1 - t_k2) of the prior (h >= 2).
    pub(crate) prior_scale: f64,
    /// Whether the history was re-queried (then d̂ depends on the observations at k1, k2).
    pub(crate) requeried: bool,
}

impl Step {
    /// A step holding nothing, to be filled by [`crate::EvoState::forward_into`]. It cannot be
    /// committed.
    pub fn empty() -> Self {
        Self {
            time: 0.0,
            frame: None,
            history: History {
                frames: [0; 3],
                len: 0,
            },
            rows: 0,
            generation: u64::MAX,
            corrected: Vec::new(),
            prior: None,
            gains: Gains::Observation,
            stats: None,
            psi_cache: None,
            memory_next: None,
            scratch: Vec::new(),
            input_mean_sq: None,
            prior_scale: 0.0,
            requeried: false,
        }
    }

    /// The query time.
    pub fn time(&self) -> f32 {
        self.time
    }

    /// The training frame at exactly this time, if any (only those can be committed).
    pub fn frame(&self) -> Option<usize> {
        self.frame
    }

    /// The history used (h = `history().len`).
    pub fn history(&self) -> History {
        self.history
    }

    /// Number of Gaussians.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// d̃, N × D: the deformation to add to the canonical raw parameters.
    pub fn corrected(&self) -> &[f32] {
        &self.corrected
    }

    /// d̂, N × D (h >= 2).
    pub fn prior(&self) -> Option<&[f32]> {
        self.prior.as_deref()
    }

    /// The gain.
    pub fn gains(&self) -> &Gains {
        &self.gains
    }

    /// Motion statistics (h = 3).
    pub fn stats(&self) -> Option<&[Stats]> {
        self.stats.as_deref()
    }

    /// Residual memory this step would commit, `m = β M[k1] + (1-β)(z - d̂)` (h >= 2).
    pub fn memory_next(&self) -> Option<&[f32]> {
        self.memory_next.as_deref()
    }

    /// Ψ's inputs after normalisation, N × (D + 3) rows `[m, |v2|, |v1|, θ]` (h = 3).
    pub fn psi_inputs(&self) -> Option<&[f32]> {
        self.stats.as_ref().map(|_| self.scratch.as_slice())
    }

    /// Per-Gaussian residual norm `|z - d̂|` of the step (`z` its observations, N × D in
    /// `layout`), relative to the scene `extent`, or `None` when the step has no prior (h < 2):
    /// one of the densification trigger's uncertainty cues (DESIGN §6.6).
    ///
    /// Only the position part is used when the layout has one: it is the only component measured
    /// in scene units, so dividing by the extent makes τ_r scene-independent. Without a position
    /// component the whole deformation vector's norm is used, unscaled (its units are raw
    /// log-scale, quaternion, logit or SH units).
    pub fn residual_norms(
        &self,
        z: &[f32],
        layout: Layout,
        extent: f32,
    ) -> Result<Option<Vec<f32>>, EvoError> {
        let d = layout.dim();
        let n = self.rows;
        let length = |what, actual| EvoError::Length {
            what,
            expected: n * d,
            actual,
        };
        if z.len() != n * d {
            return Err(length("observation z", z.len()));
        }
        let Some(prior) = self.prior() else {
            return Ok(None);
        };
        if prior.len() != n * d {
            return Err(length("step prior", prior.len()));
        }
        if !(extent.is_finite() && extent > 0.0) {
            return Err(EvoError::Extent(extent));
        }
        let (range, scale) = match layout.range(Component::Position) {
            Some(r) => (r, 1.0 / extent),
            None => (0..d, 1.0),
        };
        let out = z
            .par_chunks(d.max(1))
            .zip(prior.par_chunks(d.max(1)))
            .map(|(z, p)| {
                let sq: f32 = range.clone().map(|j| (z[j] - p[j]) * (z[j] - p[j])).sum();
                sq.sqrt() * scale
            })
            .collect();
        Ok(Some(out))
    }

    /// Per-Gaussian angular deviation θ of the step, or `None` when it has no statistics
    /// (h < 3): the trigger's other cue (DESIGN §6.6).
    pub fn thetas(&self) -> Option<Vec<f32>> {
        self.stats().map(|s| s.iter().map(|s| s.theta).collect())
    }
}

/// The EvoGS loss terms (unweighted).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Losses {
    /// L_sup = mean_i |d̃_i - z_i|².
    pub sup: f64,
    /// L_prior = mean_i sg(opacity_i) |sg(d̂_i) - z_i|² (0 when h < 2).
    pub prior: f64,
}

/// dL/d(observation at a history time), for history re-queried from Φ.
#[derive(Debug, Clone, PartialEq)]
pub struct HistoryGrads {
    /// The history frame's time: Φ was queried at it.
    pub time: f32,
    /// dL/dz(time), N × D.
    pub dz: Vec<f32>,
}

/// Gradients of `L_render + λ1 L_sup + λ2 L_prior`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Backward {
    /// dL/dz, N × D: pass it on to the observation network Φ.
    pub dz: Vec<f32>,
    /// dL/dΨ-parameters, in [`crate::GainNet::params`] order (learned gain, h = 3).
    pub dpsi: Option<Vec<f32>>,
    /// With history re-queried from Φ (h >= 2): dL/dz at the history frames k1 and k2, through
    /// d̂ = z_k1 + s (z_k1 - z_k2) (the rendering loss and L_sup; L_prior stops d̂'s gradient).
    /// Pass each on to Φ at its time. Empty with the buffer (d̂ is then a constant).
    pub history: Vec<HistoryGrads>,
    /// The loss values of this step.
    pub losses: Losses,
}
