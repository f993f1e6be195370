//! The output of a densification step: a [`RowPlan`] plus the values of the new rows'
//! overridden parameters and the rows whose opacity is reset.

use splat_core::RowPlan;
use std::fmt;

/// Parameter values of the appended rows, one entry per row of `rows.parent_from_new`, in that
/// order. Every other per-Gaussian datum of a new row (higher SH coefficients, evolution buffer
/// rows and memory) is copied from its parent; optimiser moments start at zero.
///
/// For a standard clone every value equals the parent's; a standard split overrides `means`
/// (sampled) and `log_scales` (parent − ln(0.8 N)); the deformation-aware policy adds α·d̃ to
/// every enabled component (position → mean, rotation → quaternion, scale → log-scale,
/// opacity → logit, colour → SH DC) before cloning or splitting.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NewValues {
    /// Means in world coordinates.
    pub means: Vec<[f32; 3]>,
    /// Natural-log scales.
    pub log_scales: Vec<[f32; 3]>,
    /// Raw quaternions `w, x, y, z` (not normalised).
    pub rotations: Vec<[f32; 4]>,
    /// Opacity logits; opacity is `sigmoid(logit)`.
    pub opacity_logits: Vec<f32>,
    /// The three SH DC (coefficient 0) values, R, G, B.
    pub sh_dc: Vec<[f32; 3]>,
}

impl NewValues {
    /// Empty, with room for `n` rows.
    pub fn with_capacity(n: usize) -> Self {
        Self {
            means: Vec::with_capacity(n),
            log_scales: Vec::with_capacity(n),
            rotations: Vec::with_capacity(n),
            opacity_logits: Vec::with_capacity(n),
            sh_dc: Vec::with_capacity(n),
        }
    }

    /// Number of new rows described.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    pub(crate) fn push(&mut self, v: &Values) {
        self.means.push(v.mean);
        self.log_scales.push(v.log_scale);
        self.rotations.push(v.rotation);
        self.opacity_logits.push(v.opacity_logit);
        self.sh_dc.push(v.sh_dc);
    }
}

/// The overridable parameters of one Gaussian.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Values {
    pub mean: [f32; 3],
    pub log_scale: [f32; 3],
    pub rotation: [f32; 4],
    pub opacity_logit: f32,
    pub sh_dc: [f32; 3],
}

/// Counts of what a plan does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PlanSummary {
    /// Gaussians before the plan.
    pub before: usize,
    /// Clones created (before pruning).
    pub cloned: usize,
    /// Gaussians split (each removed and replaced by its children).
    pub split: usize,
    /// Children created by splits (before pruning).
    pub children: usize,
    /// Removed for opacity < `min_opacity` (old or new rows).
    pub pruned_opacity: usize,
    /// Removed for a screen radius above the limit (old rows only: new rows have no screen
    /// statistics yet).
    pub pruned_screen: usize,
    /// Removed for a world size above the limit (old or new rows).
    pub pruned_world: usize,
    /// Gaussians with a large gradient that the uncertainty-aware trigger kept from densifying
    /// (`None` when the trigger is off).
    pub blocked: Option<usize>,
    /// Gaussians with a large gradient left undensified by `max_gaussians`.
    pub capped: usize,
    /// Rows whose opacity is reset.
    pub reset: usize,
    /// Gaussians after the plan.
    pub after: usize,
}

impl PlanSummary {
    /// All pruned rows.
    pub fn pruned(&self) -> usize {
        self.pruned_opacity + self.pruned_screen + self.pruned_world
    }
}

impl fmt::Display for PlanSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "cloned {}, split {} ({} children), pruned {} (opacity {}, screen {}, world {}), ",
            self.cloned,
            self.split,
            self.children,
            self.pruned(),
            self.pruned_opacity,
            self.pruned_screen,
            self.pruned_world
        )?;
        if let Some(b) = self.blocked {
            write!(f, "blocked {b}, ")?;
        }
        if self.capped > 0 {
            write!(f, "capped {}, ", self.capped)?;
        }
        write!(f, "reset {} → {} Gaussians", self.reset, self.after)
    }
}

/// One densification step's plan, applied to every per-Gaussian array by
/// [`crate::apply::apply_plan`].
#[derive(Debug, Clone, PartialEq)]
pub struct DensifyPlan {
    /// Which old rows stay and which new rows come from which parent.
    pub rows: RowPlan,
    /// Rows the plan was made for.
    pub old_len: usize,
    /// Overridden parameter values of the new rows.
    pub new_values: NewValues,
    /// Rows (indices after the plan, increasing) whose opacity becomes
    /// min(opacity, `reset_opacity`) and whose opacity moments are zeroed.
    pub reset_rows: Vec<u32>,
    /// The opacity (not logit) of a reset.
    pub reset_opacity: f32,
    /// Whether the densification statistics restart from zero (3DGS does so after every
    /// densify-and-prune step; an opacity reset alone keeps them).
    pub clears_stats: bool,
    /// What the plan does.
    pub summary: PlanSummary,
}

impl DensifyPlan {
    /// The plan that changes nothing for `rows` Gaussians.
    pub fn identity(rows: usize) -> Self {
        Self {
            rows: RowPlan::identity(rows),
            old_len: rows,
            new_values: NewValues::default(),
            reset_rows: Vec::new(),
            reset_opacity: 0.01,
            clears_stats: false,
            summary: PlanSummary {
                before: rows,
                after: rows,
                ..PlanSummary::default()
            },
        }
    }

    /// Rows after the plan.
    pub fn new_len(&self) -> usize {
        self.rows.new_len()
    }

    /// Number of kept old rows (new rows follow them).
    pub fn kept_len(&self) -> usize {
        self.rows.kept.len()
    }

    /// The reset value as an opacity logit.
    pub fn reset_logit(&self) -> f32 {
        splat_core::logit(self.reset_opacity)
    }
}
