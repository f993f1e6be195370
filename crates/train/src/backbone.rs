//! The deformation-backbone interface and the D-3DGS backbone on it.
//!
//! A backbone maps the canonical Gaussians and a time to per-Gaussian deformations, N × 10 rows
//! `[position 3, rotation 4, scale 3]` added to the raw mean, raw quaternion and log-scale
//! ([`DEFORM_DIM`]). It keeps what its backward pass needs from the last forward, exposes its
//! parameter buffers (for Adam, checkpoints and weight files) and, when it holds per-Gaussian
//! rows of its own (EvoGS's evolution state, issue T2), hands them to densification so they
//! stay aligned with the Gaussians.

use std::path::Path;

use densify::PerGaussian;
use splat_raster::GaussiansView;
use tiny_nn::{DeformCache, DeformConfig, DeformNet, Parameters, Precision, StoreMut, StoreRef};

use crate::config::NetSettings;
use crate::error::TrainError;

/// Width of a deformation row: position 3, rotation 4, scale 3.
pub const DEFORM_DIM: usize = 10;

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

    /// Per-Gaussian arrays the backbone holds (none for D-3DGS), for densification plans.
    fn rows_mut(&mut self) -> Vec<&mut dyn PerGaussian> {
        Vec::new()
    }

    /// Writes the weights to a safetensors file (atomically).
    fn save(&self, path: &Path) -> Result<(), TrainError>;

    /// Reads weights written by [`Backbone::save`] (same names, dtypes and sizes).
    fn load(&mut self, path: &Path) -> Result<(), TrainError>;
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
        let out = self
            .net
            .forward_reusing(&self.positions, &self.times, n, &mut cache)?;
        if training {
            self.cache = Some(cache);
        }
        Ok(out)
    }

    fn backward(&mut self, d_deform: &[f32]) -> Result<Vec<Vec<f32>>, TrainError> {
        let cache = self.cache.as_ref().ok_or_else(|| {
            TrainError::config("backbone", "backward called without a training forward")
        })?;
        let g = self.net.backward(cache, d_deform, false)?;
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
