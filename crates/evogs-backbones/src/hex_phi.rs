//! EvoGS(4DGaussians)'s Φ (`--method evogs --backbone 4dgs`): the 4DGaussians field
//! ([`tiny_nn::HexDeformNet`], the backbone's D-NeRF HexPlane of [`crate::HexBackbone`]) at half
//! its decoder width, wrapped by [`crate::EvoBackbone`] as every Φ.
//!
//! - The field: [`HexDeformConfig::dnerf`] over the initial cube with the feature layer and heads
//!   at half of 4DGaussians' `net_width` (64 → 32); its heads' last layers start at zero, so Φ's
//!   first observation is 0 (as the tri-plane Φ and Grid4D's Φ).
//! - Components: 4DGaussians' heads deform position, rotation and scale; Φ refuses other
//!   components (one-line error).
//! - Its plane regularisers (the backbone's weights, [`crate::hex_backbone::SPACE_SMOOTHNESS`],
//!   …) are added to Φ's gradients and to the backbone's loss terms; the planes train at
//!   [`crate::hex_backbone::GRID_LR_SCALE`] × the network schedule, as in the baseline.

use evo_state::Layout;
use tiny_nn::{HexDeformCache, HexDeformConfig, HexDeformGrads, HexDeformNet, Parameters};
use tiny_nn::{StoreMut, StoreRef};

use crate::error::BackboneError;
use crate::evo_settings::EvoSettings;
use crate::hex_backbone::{GRID_LR_SCALE, SPACE_SMOOTHNESS, TIME_L1, TIME_SMOOTHNESS};
use crate::observer::Observer;

/// EvoGS(4DGS)'s Φ.
pub struct HexPhi {
    net: HexDeformNet,
}

impl HexPhi {
    /// Φ for a run (its EvoGS settings, the half extent `h` of its initial cube `[-h, h]³`, its
    /// seed): errors unless the components are position, rotation and scale.
    pub fn new(settings: &EvoSettings, half_extent: f32, seed: u64) -> Result<Self, BackboneError> {
        let layout = settings.evo.layout;
        if layout != Layout::default() {
            return Err(BackboneError::config(
                "evogs.components",
                format!(
                    "`{layout}`: EvoGS(4dgs)'s Φ has 4DGaussians' heads, position, rotation and \
                     scale only"
                ),
            ));
        }
        let mut net = HexDeformNet::new(Self::config(settings, half_extent, seed))?;
        // Zero each head's last layer (its weights and bias: the last `W · out + out` values).
        for head in &mut net.heads {
            let mut p = head.params().to_vec_f32();
            let last = head
                .layers()
                .last()
                .map_or(0, |l| l.input * l.output + l.output);
            let n = p.len();
            p[n - last..].fill(0.0);
            head.set_params(&p)?;
        }
        Ok(Self { net })
    }

    /// The field [`HexPhi::new`] builds (before its heads' last layers are zeroed).
    pub(crate) fn config(settings: &EvoSettings, half_extent: f32, seed: u64) -> HexDeformConfig {
        let h = half_extent;
        let mut c = HexDeformConfig::dnerf([-h; 3], [h; 3], seed ^ 0xE74D_6500);
        c.width = (c.width / 2).max(1);
        c.precision = settings.net_precision;
        c
    }

    /// The field.
    pub fn net(&self) -> &HexDeformNet {
        &self.net
    }
}

impl Parameters for HexPhi {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.net.named_params()
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.net.named_params_mut()
    }
}

impl Observer for HexPhi {
    type Cache = Option<HexDeformCache>;

    fn output_width(&self) -> usize {
        tiny_nn::HEX_OUTPUT
    }

    fn observe_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut Option<HexDeformCache>,
    ) -> Result<Vec<f32>, BackboneError> {
        let (z, c) = self.net.forward(positions, times, rows)?;
        *cache = Some(c);
        Ok(z)
    }

    fn gradients(
        &self,
        cache: &Option<HexDeformCache>,
        dz: &[f32],
    ) -> Result<Vec<Vec<f32>>, BackboneError> {
        let cache = cache
            .as_ref()
            .ok_or_else(|| BackboneError::config("backbone", "Φ's backward without a forward"))?;
        let g = self.net.backward(cache, dz)?;
        let [p, r, s] = g.heads;
        Ok(vec![g.hexplane, g.trunk, p, r, s])
    }

    fn regularise(
        &mut self,
        _cache: &Option<HexDeformCache>,
        grads: &mut [Vec<f32>],
    ) -> Result<f64, BackboneError> {
        let planes = grads
            .first_mut()
            .ok_or_else(|| BackboneError::config("backbone", "Φ has no plane gradient"))?;
        let mut g = HexDeformGrads {
            hexplane: std::mem::take(planes),
            trunk: Vec::new(),
            heads: Default::default(),
        };
        let value = self
            .net
            .regularise(SPACE_SMOOTHNESS, TIME_SMOOTHNESS, TIME_L1, &mut g)?;
        *planes = g.hexplane;
        Ok(value)
    }

    fn lr_scale(&self, name: &str, _grid_lr_scale: f32) -> f32 {
        if name == "hexplane" {
            GRID_LR_SCALE
        } else {
            1.0
        }
    }
}
