//! `densify`: 3DGS adaptive density control (clone, split, prune, opacity reset) and EvoGS's
//! uncertainty-aware trigger and deformation-aware clone/split (DESIGN §6), expressed as plans.
//!
//! Flow per training iteration:
//! 1. [`DensifyStats::add_view`] with the rasterizer's per-Gaussian dL/d(projected mean) and
//!    screen radii; [`DensifyStats::add_evolution`] with the per-Gaussian residual norms and θ of
//!    the deformation's step (EvoGS trigger; evo-state's `Step::residual_norms` and
//!    `Step::thetas` compute them).
//! 2. When [`Schedule::acts`], [`make_plan`] decides, deterministically for a seed, and returns a
//!    [`DensifyPlan`]: a [`splat_core::RowPlan`], the new rows' parameter values, and
//!    the rows whose opacity is reset.
//! 3. [`apply_plan`] applies it to every per-Gaussian container through one trait,
//!    [`PerGaussian`] (Gaussians, Adam moments, statistics, any other rows: a deformation's
//!    per-Gaussian state, such as EvoGS's evolution state, implements it beside its backbone), and
//!    checks that all end with the same length.
//!
//! It is not a trainer: it renders nothing, computes no gradients and steps no optimiser; it
//! reads plain slices from the rasterizer (`means2d`: dL/d projected mean in pixels, `radii`: px,
//! 0 when culled) and the deformation's per-Gaussian cues and rows, and depends on neither the
//! rasterizer nor the evolution state (gsplat's strategies are generic in the same way: what is
//! specific to a dynamic scene sits beside them).
//!
//! Choices where DESIGN §6 is silent (details in each module):
//! - Conditions and order are those of 3DGS's `train.py` / `densify_and_prune` (see
//!   [`config::Schedule`], [`planner`]); the one deliberate difference is that the screen-size
//!   prune reads the interval's maximum radius (the original zeroes it just before reading it).
//! - Clones and split children are pruned in the same step when they qualify (opacity, world
//!   size), as in 3DGS; new rows are never screen-pruned (no screen statistics yet).
//! - EvoGS trigger defaults τ_r = 0.01 (position residual / extent) and τ_θ = π/3, reasoned in
//!   [`config::Trigger`]; a Gaussian without samples passes.
//! - Deformation-aware policy: clone/split decisions use canonical parameters; the new rows'
//!   values start from canonical + α·d̃; without a deformation d̃ is taken as 0.
//! - New rows start with zero Adam moments; statistics restart at zero after every densification
//!   step; an opacity reset zeroes only the opacity moments.

pub mod apply;
pub mod config;
pub mod error;
pub mod extent;
pub mod math;
pub mod plan;
pub mod planner;
pub mod stats;

pub use apply::{Moments, OptimiserMoments, PerGaussian, Planned, Rows, apply_plan};
pub use config::{DensifyConfig, Schedule, Trigger};
pub use error::DensifyError;
pub use extent::scene_extent;
pub use plan::{DensifyPlan, NewValues, PlanSummary};
pub use planner::{Deformation, PlanInput, make_plan};
pub use stats::DensifyStats;
