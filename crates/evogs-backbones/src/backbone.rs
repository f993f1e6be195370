//! The deformation-backbone interface and the helpers its backbones share.
//!
//! A backbone maps the canonical Gaussians and a time to per-Gaussian deformation rows in its own
//! [`Layout`] ([`Backbone::layout`]: D-3DGS's, 4DGaussians' and Grid4D's heads give position,
//! rotation and scale, [`Layout::GEOMETRY`]; EvoGS the components of its evolution state), which
//! `splat_core::DeformedGeometry` adds to the raw mean, raw quaternion, log-scale, opacity logit
//! and SH DC. It keeps what its backward pass needs from the last forward and exposes its
//! parameter buffers (for Adam, checkpoints and weight files): that is the whole of [`Backbone`].
//! When it holds per-Gaussian rows of its own (EvoGS's evolution state) it also implements
//! [`PerGaussianState`], which hands them to densification so they stay aligned with the
//! Gaussians.

use std::path::Path;

use densify::PerGaussian;
use serde::{Deserialize, Serialize};
use splat_core::{GaussiansView, Layout};
use tiny_nn::{StoreMut, StoreRef};

use crate::error::BackboneError;

/// A deformation backbone: the core every backbone implements (forward, backward, parameters,
/// weights). A backbone that keeps per-Gaussian state of its own (EvoGS's evolution state) also
/// implements [`PerGaussianState`] and returns it from [`Backbone::state`] and
/// [`Backbone::state_mut`]; one without (D-3DGS, HexPlane) implements nothing more. The trainer
/// reaches the state through the methods of `dyn Backbone` (`prepare`, `rows_mut`,
/// `densify_cues`, …), which answer "nothing" for a backbone without state.
pub trait Backbone: Send {
    /// Short name for messages and files.
    fn name(&self) -> &'static str;

    /// Places what the backbone derives from the canonical Gaussians (SC-GS: its control
    /// points, by farthest-point sampling of them). The trainer calls it for a new run before
    /// the optimiser is built, and again at the step the deformation starts (after the static
    /// warm-up, on the Gaussians it fitted; the backbone has had no gradient yet); a resumed run
    /// reads the result from its checkpoint. Nothing by default.
    fn initialise(&mut self, _canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        Ok(())
    }

    /// Called after a training step whose densification changed the canonical Gaussians (once
    /// the deformation is in use), with the new set. Nothing by default; SC-GS's control points
    /// move to the new Gaussians when its settings say so.
    fn gaussians_changed(&mut self, _canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        Ok(())
    }

    /// The points that carry the motion at `time`, for drawing the motion skeleton (SC-GS: its
    /// control points, canonical position plus the network's translation); `None` for a backbone
    /// without such points (every other).
    fn control_points_at(&mut self, _time: f32) -> Result<Option<Vec<[f32; 3]>>, BackboneError> {
        Ok(None)
    }

    /// Deformation rows of the canonical Gaussians at `time` into `out` (N × `layout().dim()`,
    /// whatever it held; the backbone reuses its allocation where it can: the trainer keeps one
    /// buffer for every iteration). `training` says whether a backward pass will follow (the
    /// backbone then keeps its cache).
    fn forward_into(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), BackboneError>;

    /// Gradients of the parameter buffers (same order as [`Backbone::params`]) into `out`,
    /// whatever it held, from dL/d(deformation rows) of the last training forward (in the same
    /// layout). Gradients to the canonical Gaussians are not returned: the network input is
    /// detached (D-3DGS: `deform.step(gaussians.get_xyz.detach(), t)`). On a device
    /// (`Backbone::use_device`, feature `wgpu`) the gradients stay there for
    /// [`Backbone::step_on_device`] and `out` is left empty.
    fn backward_into(
        &mut self,
        d_deform: &[f32],
        out: &mut Vec<Vec<f32>>,
    ) -> Result<(), BackboneError>;

    /// [`Backbone::forward_into`] into a new buffer.
    fn forward(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
    ) -> Result<Vec<f32>, BackboneError> {
        let mut out = Vec::new();
        self.forward_into(canonical, time, training, &mut out)?;
        Ok(out)
    }

    /// [`Backbone::backward_into`] into a new list.
    fn backward(&mut self, d_deform: &[f32]) -> Result<Vec<Vec<f32>>, BackboneError> {
        let mut out = Vec::new();
        self.backward_into(d_deform, &mut out)?;
        Ok(out)
    }

    /// Runs the backbone's network and its optimiser's steps on `ctx`'s device from now on,
    /// when the backbone has a device form (D-3DGS's network today: the same rows, gradients
    /// and updates up to f32 rounding); `Ok(false)`, and nothing changes, for a backbone
    /// without one (every other, the default). Cargo feature `wgpu`.
    ///
    /// On the device the parameters and their Adam moments live there from the first
    /// [`Backbone::step_on_device`]: [`Backbone::backward_into`] returns no gradient, the caller
    /// steps with [`Backbone::step_on_device`] instead of [`Backbone::params_mut`], and calls
    /// [`Backbone::sync_to_host`] before it reads [`Backbone::params`] or the moments (a
    /// checkpoint, a weight file, a check for non-finite values).
    #[cfg(feature = "wgpu")]
    fn use_device(
        &mut self,
        _ctx: &std::sync::Arc<gpu_core::GpuContext>,
    ) -> Result<bool, BackboneError> {
        Ok(false)
    }

    /// One Adam update of every parameter buffer on the device (after `Backbone::use_device`
    /// and a training [`Backbone::backward_into`]), with the constants `updates` (one per buffer,
    /// in [`Backbone::params`]' order, from [`tiny_nn::Adam::next_update`]) and the host's
    /// moments of those groups, `moments`, which the first step uploads (later ones use the
    /// device's). An error for a backbone on the host (the default).
    fn step_on_device(
        &mut self,
        _updates: &[tiny_nn::AdamUpdate],
        _moments: &[&tiny_nn::AdamGroup],
    ) -> Result<(), BackboneError> {
        Err(BackboneError::config(
            "net_backend",
            format!(
                "the {} backbone steps its parameters on the host",
                self.name()
            ),
        ))
    }

    /// Copies what the device holds of the parameters into the host's buffers
    /// ([`Backbone::params`]) and of their Adam moments into `moments` (one group per buffer);
    /// nothing when the host's are the current ones (on the host, the default; on a device
    /// before its first step).
    fn sync_to_host(
        &mut self,
        _moments: &mut [&mut tiny_nn::AdamGroup],
    ) -> Result<(), BackboneError> {
        Ok(())
    }

    /// Named parameter buffers, in a fixed order.
    fn params(&self) -> Vec<(String, StoreRef<'_>)>;

    /// The same buffers, mutable.
    fn params_mut(&mut self) -> Vec<(String, StoreMut<'_>)>;

    /// Factor on the network lr schedule for the parameter buffer `name` (1 for D-3DGS).
    fn lr_scale(&self, _name: &str) -> f32 {
        1.0
    }

    /// A schedule of the backbone's own for the parameter buffer `name`, replacing the network
    /// schedule (EvoGS: Ψ's `--psi-lr`); `None` (every D-3DGS buffer) means the network schedule
    /// times [`Backbone::lr_scale`].
    fn own_schedule(&self, _name: &str) -> Option<tiny_nn::LrSchedule> {
        None
    }

    /// The components of its rows, in order ([`Layout::GEOMETRY`] for D-3DGS, 4DGaussians and
    /// Grid4D; EvoGS's evolution layout).
    fn layout(&self) -> Layout {
        Layout::GEOMETRY
    }

    /// The backbone's own weighted loss terms of the last backward (EvoGS: λ1 L_sup + λ2 L_prior;
    /// HexPlane: its grid regularisers; 0 for D-3DGS).
    fn loss_terms(&self) -> f64 {
        0.0
    }

    /// Writes the weights to a safetensors file (atomically).
    fn save(&self, path: &Path) -> Result<(), BackboneError>;

    /// Reads weights written by [`Backbone::save`] (same names, dtypes and sizes).
    fn load(&mut self, path: &Path) -> Result<(), BackboneError>;

    /// The backbone's per-Gaussian state, when it has one (EvoGS; `None` for D-3DGS).
    fn state(&self) -> Option<&dyn PerGaussianState> {
        None
    }

    /// The same state, mutable.
    fn state_mut(&mut self) -> Option<&mut dyn PerGaussianState> {
        None
    }
}

/// The optional part of a backbone: per-Gaussian state of its own (EvoGS's evolution state, with
/// its history, residual memory and last step), kept aligned with the Gaussians through
/// densification's plans, saved beside the checkpoint, and read by the densification trigger and
/// the reports.
pub trait PerGaussianState: Send {
    /// Sizes the state for a run (training frame times, Gaussian count, scene extent); called
    /// when a trainer is built.
    fn prepare(
        &mut self,
        frame_times: &[f32],
        rows: usize,
        extent: f32,
    ) -> Result<(), BackboneError>;

    /// The per-Gaussian arrays of the state, for densification plans.
    fn rows_mut(&mut self) -> Vec<&mut dyn PerGaussian>;

    /// Rows of the state, to check alignment with the Gaussians.
    fn rows(&self) -> usize;

    /// Bytes the state stores (EvoGS: its buffer and residual memory).
    fn state_bytes(&self) -> usize;

    /// Uncertainty cues of the last training step for densification's trigger.
    fn densify_cues(&self, extent: f32) -> Result<DensifyCues, BackboneError>;

    /// Motion statistics (|v1|, |v2|, θ per Gaussian) of the last training step, when it had
    /// three history frames.
    fn motion_stats(&self) -> Option<&[evo_state::Stats]>;

    /// The last training step of the evolution (its gains, statistics and frame), for the gain
    /// report.
    fn latest_step(&self) -> Option<&evo_state::Step>;

    /// The latest training step's deformation for deformation-aware densification.
    fn latest_deformation(&self) -> Option<densify::Deformation<'_>>;

    /// Statistics of the gain K of the latest training step.
    fn gain_stats(&self) -> Option<GainStats>;

    /// Writes the state to `path`.
    fn save_state(&self, path: &Path) -> Result<(), BackboneError>;

    /// Reads the state written by [`PerGaussianState::save_state`].
    fn load_state(&mut self, path: &Path) -> Result<(), BackboneError>;
}

/// The per-Gaussian state of any backbone, through [`Backbone::state`]: what a backbone without
/// state answers is said once here ("nothing").
impl<'a> dyn Backbone + 'a {
    /// Sizes the state for a run ([`PerGaussianState::prepare`]); nothing to do without state.
    pub fn prepare(
        &mut self,
        frame_times: &[f32],
        rows: usize,
        extent: f32,
    ) -> Result<(), BackboneError> {
        self.state_mut()
            .map_or(Ok(()), |s| s.prepare(frame_times, rows, extent))
    }

    /// The state's per-Gaussian arrays (none without state).
    pub fn rows_mut(&mut self) -> Vec<&mut dyn PerGaussian> {
        self.state_mut().map_or_else(Vec::new, |s| s.rows_mut())
    }

    /// Rows of the state (`None` without state), to check alignment with the Gaussians.
    pub fn state_rows(&self) -> Option<usize> {
        self.state().map(|s| s.rows())
    }

    /// Bytes of per-Gaussian state (0 without state).
    pub fn state_bytes(&self) -> usize {
        self.state().map_or(0, |s| s.state_bytes())
    }

    /// Uncertainty cues of the last training step (none without state).
    pub fn densify_cues(&self, extent: f32) -> Result<DensifyCues, BackboneError> {
        self.state()
            .map_or_else(|| Ok(DensifyCues::default()), |s| s.densify_cues(extent))
    }

    /// Motion statistics of the last training step (none without state).
    pub fn motion_stats(&self) -> Option<&[evo_state::Stats]> {
        self.state()?.motion_stats()
    }

    /// The last training step of the evolution (none without state).
    pub fn latest_step(&self) -> Option<&evo_state::Step> {
        self.state()?.latest_step()
    }

    /// The latest training step's deformation (none without state).
    pub fn latest_deformation(&self) -> Option<densify::Deformation<'_>> {
        self.state()?.latest_deformation()
    }

    /// Statistics of the gain K of the latest training step (none without state).
    pub fn gain_stats(&self) -> Option<GainStats> {
        self.state()?.gain_stats()
    }

    /// Writes the state to `path`; returns whether there was any (without state nothing is
    /// written).
    pub fn save_state(&self, path: &Path) -> Result<bool, BackboneError> {
        match self.state() {
            Some(s) => s.save_state(path).map(|()| true),
            None => Ok(false),
        }
    }

    /// Reads the state written by [`PerGaussianState::save_state`] (nothing without state).
    pub fn load_state(&mut self, path: &Path) -> Result<(), BackboneError> {
        self.state_mut().map_or(Ok(()), |s| s.load_state(path))
    }
}

/// Statistics of K over the Gaussians of one step (EvoGS).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GainStats {
    /// Mean K.
    pub mean: f64,
    /// Smallest K.
    pub min: f32,
    /// Largest K.
    pub max: f32,
}

impl GainStats {
    /// The statistics of `gains` over `rows` Gaussians (`None` for no rows).
    pub fn of(gains: &evo_state::Gains, rows: usize) -> Option<Self> {
        if rows == 0 {
            return None;
        }
        let (mut sum, mut min, mut max) = (0.0f64, f32::INFINITY, f32::NEG_INFINITY);
        for i in 0..rows {
            let k = gains.at(i);
            sum += f64::from(k);
            min = min.min(k);
            max = max.max(k);
        }
        Some(Self {
            mean: sum / rows as f64,
            min,
            max,
        })
    }
}

/// Per-Gaussian uncertainty cues of a training step, for densify's trigger.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DensifyCues {
    /// Residual norm relative to the extent (when the step had a prior).
    pub residual_norm: Option<Vec<f32>>,
    /// Angular deviation θ (when the step had statistics).
    pub theta: Option<Vec<f32>>,
}

/// A backbone's network inputs for a forward at `time`: the canonical means, flattened (N × 3),
/// into `positions`, and `time` once per Gaussian into `times` (both cleared first).
pub(crate) fn fill_inputs(
    canonical: GaussiansView<'_>,
    time: f32,
    positions: &mut Vec<f32>,
    times: &mut Vec<f32>,
) {
    positions.clear();
    positions.extend_from_slice(canonical.means.as_flattened());
    times.clear();
    times.resize(canonical.len(), time);
}

/// The error of a backward pass that has no training forward to go back through.
pub(crate) fn no_training_forward() -> BackboneError {
    BackboneError::config("backbone", "backward called without a training forward")
}
