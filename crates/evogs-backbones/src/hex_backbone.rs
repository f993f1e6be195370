//! The 4DGaussians backbone (`--backbone 4dgs`): its HexPlane deformation field
//! ([`tiny_nn::HexDeformNet`]) with its plane regularisers.
//!
//! What it is (`hustvl/4DGaussians`, D-NeRF settings `arguments/dnerf/dnerf_default.py`):
//! - the field: HexPlane of 32 channels, space resolutions 64 · [1, 2], 25 time texels, feature
//!   layer and heads of width 64 ([`HexDeformConfig::dnerf`]), over the box of the initial
//!   points (4DGaussians: `set_aabb` from the initial point cloud's bounds; ours is the cube
//!   `[-h, h]³` of the trainer's `init_half_extent`);
//! - deformation of position, rotation and scale (its D-NeRF defaults `no_do`, `no_dshs`);
//! - the regularisers of the fine stage (`train.py` `scene_reconstruction`, `stage == "fine"`):
//!   `plane_tv_weight = 1e-4` ([`SPACE_SMOOTHNESS`]), `time_smoothness_weight = 1e-2`
//!   ([`TIME_SMOOTHNESS`]), `l1_time_planes = 1e-4` ([`TIME_L1`]); the field runs only after
//!   the warm-up, so its regularisers are those of the fine stage;
//! - learning rates: 4DGaussians' grid lr is 10× its MLP lr (`grid_lr_init = 1.6e-3`,
//!   `deformation_lr_init = 1.6e-4`, both decaying 100×), so the planes take the network
//!   schedule times [`GRID_LR_SCALE`] and the MLPs the network schedule.
//! - the two-stage schedule: 4DGaussians' static coarse stage (`coarse_iterations = 3000`) is
//!   the trainer's warm-up (its `warm_up`), during which no backbone runs.
//!
//! EvoGS(4DGS), Φ built from this field at half its width, is [`crate::hex_phi::HexPhi`].

use std::path::Path;

use splat_core::GaussiansView;
use tiny_nn::{HexDeformCache, HexDeformConfig, HexDeformNet, Parameters, StoreMut, StoreRef};

use crate::backbone::{Backbone, fill_inputs, no_training_forward};
use crate::error::BackboneError;

/// 4DGaussians' `plane_tv_weight` (D-NeRF).
pub const SPACE_SMOOTHNESS: f32 = 1e-4;
/// 4DGaussians' `time_smoothness_weight` (D-NeRF).
pub const TIME_SMOOTHNESS: f32 = 1e-2;
/// 4DGaussians' `l1_time_planes` (D-NeRF).
pub const TIME_L1: f32 = 1e-4;
/// 4DGaussians' `grid_lr_init / deformation_lr_init`.
pub const GRID_LR_SCALE: f32 = 10.0;

/// The 4DGaussians backbone.
pub struct HexBackbone {
    net: HexDeformNet,
    cache: Option<HexDeformCache>,
    regularisers: f64,
}

impl HexBackbone {
    /// The D-NeRF field over the initial cube `[-h, h]³` (`h = half_extent`), initialised from
    /// the run's `seed`.
    pub fn new(half_extent: f32, seed: u64) -> Result<Self, BackboneError> {
        let net = HexDeformNet::new(Self::config(half_extent, seed))?;
        Ok(Self {
            net,
            cache: None,
            regularisers: 0.0,
        })
    }
}

impl HexBackbone {
    /// The field [`HexBackbone::new`] builds.
    pub(crate) fn config(half_extent: f32, seed: u64) -> HexDeformConfig {
        let h = half_extent;
        HexDeformConfig::dnerf([-h; 3], [h; 3], seed ^ 0x4D65_0000)
    }
}

impl Backbone for HexBackbone {
    fn name(&self) -> &'static str {
        "4dgs"
    }

    fn forward_into(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), BackboneError> {
        let n = canonical.len();
        let (mut positions, mut times) = (Vec::new(), Vec::new());
        fill_inputs(canonical, time, &mut positions, &mut times);
        let (geometry, cache) = self.net.forward(&positions, &times, n)?;
        self.cache = training.then_some(cache);
        // The field's heads are the rows: position, rotation, scale (`Layout::GEOMETRY`).
        *out = geometry;
        Ok(())
    }

    fn backward_into(
        &mut self,
        d_deform: &[f32],
        out: &mut Vec<Vec<f32>>,
    ) -> Result<(), BackboneError> {
        let cache = self.cache.as_ref().ok_or_else(no_training_forward)?;
        let mut g = self.net.backward(cache, d_deform)?;
        self.regularisers =
            self.net
                .regularise(SPACE_SMOOTHNESS, TIME_SMOOTHNESS, TIME_L1, &mut g)?;
        let [p, r, s] = g.heads;
        *out = vec![g.hexplane, g.trunk, p, r, s];
        Ok(())
    }

    fn params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.net.named_params()
    }

    fn params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.net.named_params_mut()
    }

    fn lr_scale(&self, name: &str) -> f32 {
        if name == "hexplane" {
            GRID_LR_SCALE
        } else {
            1.0
        }
    }

    fn loss_terms(&self) -> f64 {
        self.regularisers
    }

    fn save(&self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::save(path, &self.net)?)
    }

    fn load(&mut self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::load(path, &mut self.net)?)
    }
}
