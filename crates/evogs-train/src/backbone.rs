//! The deformation-backbone interface and the D-3DGS backbone on it.
//!
//! A backbone maps the canonical Gaussians and a time to per-Gaussian deformations, N × 14 rows
//! `[position 3, rotation 4, scale 3, opacity 1, colour 3]` added to the raw mean, raw
//! quaternion, log-scale, opacity logit and SH DC ([`DEFORM_DIM`]). The appearance columns are
//! used only where the backbone says so ([`Backbone::appearance`]; EvoGS's optional components);
//! D-3DGS deforms geometry only and leaves them zero. It keeps what its backward pass needs from the last forward, exposes its
//! parameter buffers (for Adam, checkpoints and weight files) and, when it holds per-Gaussian
//! rows of its own (EvoGS's evolution state, issue T2), hands them to densification so they
//! stay aligned with the Gaussians.

use std::path::Path;

use densify::PerGaussian;
use splat_raster::GaussiansView;
use tiny_nn::{DeformCache, DeformConfig, DeformNet, Parameters, Precision, StoreMut, StoreRef};

use crate::config::{NetInit, NetSettings};
use crate::deformed::Appearance;
use crate::error::TrainError;

/// Width of a deformation row: position 3, rotation 4, scale 3, opacity 1, colour (SH DC) 3.
pub const DEFORM_DIM: usize = 14;
/// The geometric part of a row (position, rotation, scale): D-3DGS's heads.
pub const GEOMETRY_DIM: usize = 10;

/// A deformation backbone.
pub trait Backbone: Send {
    /// Short name for messages and files.
    fn name(&self) -> &'static str;

    /// Deformations (N × [`DEFORM_DIM`]) of the canonical Gaussians at `time`. `training` says
    /// whether a backward pass will follow (the backbone then keeps its cache).
    fn forward(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
    ) -> Result<Vec<f32>, TrainError>;

    /// Gradients of the parameter buffers (same order as [`Backbone::params`]) from dL/d(deformation)
    /// of the last training forward. Gradients to the canonical Gaussians are not returned: the
    /// network input is detached (D-3DGS: `deform.step(gaussians.get_xyz.detach(), t)`).
    fn backward(&mut self, d_deform: &[f32]) -> Result<Vec<Vec<f32>>, TrainError>;

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

    /// Which appearance columns of its rows the backbone deforms (none for D-3DGS).
    fn appearance(&self) -> Appearance {
        Appearance::default()
    }

    /// Per-Gaussian arrays the backbone holds (none for D-3DGS), for densification plans.
    fn rows_mut(&mut self) -> Vec<&mut dyn PerGaussian> {
        Vec::new()
    }

    /// Sizes the backbone's per-Gaussian state for a run (training frame times, Gaussian count,
    /// scene extent); called when a trainer is built. Nothing to do for D-3DGS.
    fn prepare(
        &mut self,
        _frame_times: &[f32],
        _rows: usize,
        _extent: f32,
    ) -> Result<(), TrainError> {
        Ok(())
    }

    /// The backbone's own weighted loss terms of the last backward (EvoGS: λ1 L_sup + λ2 L_prior;
    /// 0 for D-3DGS).
    fn loss_terms(&self) -> f64 {
        0.0
    }

    /// Uncertainty cues of the last training step for densification's trigger (none for D-3DGS).
    fn densify_cues(&self, _extent: f32) -> Result<DensifyCues, TrainError> {
        Ok(DensifyCues::default())
    }

    /// Motion statistics (|v1|, |v2|, θ per Gaussian) of the last training step, when it had
    /// three history frames (none for D-3DGS).
    fn motion_stats(&self) -> Option<&[evo_state::Stats]> {
        None
    }

    /// The last training step of the evolution (its gains, statistics and frame), for the gain
    /// report (none for D-3DGS).
    fn latest_step(&self) -> Option<&evo_state::Step> {
        None
    }

    /// The latest training step's deformation for deformation-aware densification (none for
    /// D-3DGS).
    fn latest_deformation(&self) -> Option<densify::Deformation<'_>> {
        None
    }

    /// Statistics of the gain K of the latest training step (EvoGS; none for D-3DGS).
    fn gain_stats(&self) -> Option<crate::train_log::GainStats> {
        None
    }

    /// Bytes of per-Gaussian state the backbone stores (EvoGS's buffer and residual memory; 0
    /// for D-3DGS).
    fn state_bytes(&self) -> usize {
        0
    }

    /// Rows of the backbone's per-Gaussian state (EvoGS: the evolution state's; `None` for
    /// D-3DGS), to check alignment with the Gaussians.
    fn state_rows(&self) -> Option<usize> {
        None
    }

    /// Writes the backbone's non-parameter state (EvoGS's evolution state) to `path`; returns
    /// whether there was any (D-3DGS: none, nothing written).
    fn save_state(&self, _path: &Path) -> Result<bool, TrainError> {
        Ok(false)
    }

    /// Reads the state written by [`Backbone::save_state`] (nothing for D-3DGS).
    fn load_state(&mut self, _path: &Path) -> Result<(), TrainError> {
        Ok(())
    }

    /// Writes the weights to a safetensors file (atomically).
    fn save(&self, path: &Path) -> Result<(), TrainError>;

    /// Reads weights written by [`Backbone::save`] (same names, dtypes and sizes).
    fn load(&mut self, path: &Path) -> Result<(), TrainError>;
}

/// Per-Gaussian uncertainty cues of a training step, for densify's trigger.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DensifyCues {
    /// Residual norm relative to the extent (when the step had a prior).
    pub residual_norm: Option<Vec<f32>>,
    /// Angular deviation θ (when the step had statistics).
    pub theta: Option<Vec<f32>>,
}

/// D-3DGS's deformation network (`utils/time_utils.py` `DeformNetwork`: sinusoidal encodings of
/// xyz (10 frequencies) and t (6 for synthetic scenes), 8 ReLU layers with the input re-joined
/// after layer 4, linear heads for position, rotation and scale), as `tiny_nn::DeformNet`.
pub struct D3dgsBackbone {
    net: DeformNet,
    cache: Option<DeformCache>,
    positions: Vec<f32>,
    times: Vec<f32>,
}

impl D3dgsBackbone {
    /// The network of the given shape, initialised from `seed`.
    pub fn new(settings: &NetSettings, seed: u64) -> Result<Self, TrainError> {
        let net = DeformNet::new(DeformConfig {
            width: settings.width,
            depth: settings.depth,
            skip_after: settings.skip_after,
            xyz_freqs: settings.xyz_freqs,
            t_freqs: settings.t_freqs,
            init: match settings.init {
                NetInit::Torch => tiny_nn::Init::Torch,
                NetInit::He => tiny_nn::Init::He,
            },
            zero_heads: settings.init == NetInit::He,
            precision: Precision::F32,
            seed,
        })?;
        Ok(Self {
            net,
            cache: None,
            positions: Vec::new(),
            times: Vec::new(),
        })
    }
}

impl Backbone for D3dgsBackbone {
    fn name(&self) -> &'static str {
        "d3dgs"
    }

    fn forward(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
    ) -> Result<Vec<f32>, TrainError> {
        let n = canonical.len();
        self.positions.clear();
        self.positions
            .extend(canonical.means.iter().flat_map(|m| m.iter().copied()));
        self.times.clear();
        self.times.resize(n, time);
        let mut cache = self.cache.take().unwrap_or_default();
        let geometry = self
            .net
            .forward_reusing(&self.positions, &self.times, n, &mut cache)?;
        if training {
            self.cache = Some(cache);
        }
        let mut out = vec![0.0f32; n * DEFORM_DIM];
        for (row, g) in out
            .chunks_exact_mut(DEFORM_DIM)
            .zip(geometry.chunks_exact(GEOMETRY_DIM))
        {
            row[..GEOMETRY_DIM].copy_from_slice(g);
        }
        Ok(out)
    }

    fn backward(&mut self, d_deform: &[f32]) -> Result<Vec<Vec<f32>>, TrainError> {
        let cache = self.cache.as_ref().ok_or_else(|| {
            TrainError::config("backbone", "backward called without a training forward")
        })?;
        let geometry: Vec<f32> = d_deform
            .chunks_exact(DEFORM_DIM)
            .flat_map(|r| r[..GEOMETRY_DIM].iter().copied())
            .collect();
        let g = self.net.backward(cache, &geometry, false)?;
        Ok(vec![g.mlp])
    }

    fn params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.net.named_params()
    }

    fn params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.net.named_params_mut()
    }

    fn save(&self, path: &Path) -> Result<(), TrainError> {
        Ok(tiny_nn::weights::save(path, &self.net)?)
    }

    fn load(&mut self, path: &Path) -> Result<(), TrainError> {
        Ok(tiny_nn::weights::load(path, &mut self.net)?)
    }
}
