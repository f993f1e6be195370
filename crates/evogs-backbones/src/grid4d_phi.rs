//! EvoGS(Grid4D)'s Φ: Grid4D's 4D decomposed hash-grid field (the Grid4D backbone's, built by
//! [`Grid4dRun::field`]) at half the run's width with one zero-initialised head per evolution
//! component, so Φ's first observation is 0 as EvoGS(D-3DGS)'s Φ; its smoothness regulariser is
//! added to Φ's gradients. [`crate::EvoBackbone`] wraps it exactly as it wraps EvoGS(D-3DGS)'s
//! tri-plane Φ. The recipe and its sources are the Grid4D backbone's (`grid4d_backbone`).

use tiny_nn::{Grid4dCache, Grid4dHead, Grid4dNet, LrSchedule, Parameters, StoreMut, StoreRef};

use crate::error::BackboneError;
use crate::evo_settings::EvoSettings;
use crate::grid4d_backbone::{Field, Grid4dRun};
use crate::observer::Observer;

/// EvoGS(Grid4D)'s Φ: Grid4D's field at half the run's width, one zero-initialised head per
/// evolution component (in the layout's order), with its smoothness regulariser.
pub struct Grid4dPhi {
    field: Field,
}

impl Grid4dPhi {
    /// Φ for `run` and its EvoGS `settings` (the components, Φ's storage), initialised from the
    /// run's seed.
    pub fn new(run: &Grid4dRun, settings: &EvoSettings) -> Result<Self, BackboneError> {
        let seed = run.seed ^ 0xE76D_4D00;
        let net = Grid4dNet::new(Self::config(run, settings))?;
        Ok(Self {
            field: Field::new(net, &run.lr, seed ^ 0x5EED),
        })
    }

    /// The field [`Grid4dPhi::new`] builds: one head per evolution component, half the
    /// baseline's width, Φ's storage precision.
    pub(crate) fn config(run: &Grid4dRun, settings: &EvoSettings) -> tiny_nn::Grid4dConfig {
        let heads = settings
            .evo
            .layout
            .components()
            .into_iter()
            .map(|(c, _)| match c {
                evo_state::Component::Position => Grid4dHead::Position,
                evo_state::Component::Rotation => Grid4dHead::Rotation,
                evo_state::Component::Scale => Grid4dHead::Scale,
                evo_state::Component::Opacity => Grid4dHead::Opacity,
                evo_state::Component::Colour => Grid4dHead::Colour,
            })
            .collect();
        let mut c = run.field((run.width / 2).max(1), heads, true, run.seed ^ 0xE76D_4D00);
        c.precision = settings.net_precision;
        c
    }

    /// The field.
    pub fn net(&self) -> &Grid4dNet {
        &self.field.net
    }
}

impl Parameters for Grid4dPhi {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.field.net.named_params()
    }
    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.field.net.named_params_mut()
    }
}

impl Observer for Grid4dPhi {
    type Cache = Grid4dCache;

    fn output_width(&self) -> usize {
        self.field.net.output_width()
    }

    fn observe_into(
        &self,
        positions: &[f32],
        times: &[f32],
        rows: usize,
        cache: &mut Grid4dCache,
    ) -> Result<Vec<f32>, BackboneError> {
        Ok(self.field.net.forward_into(positions, times, rows, cache)?)
    }

    fn gradients(&self, cache: &Grid4dCache, dz: &[f32]) -> Result<Vec<Vec<f32>>, BackboneError> {
        Ok(self.field.net.backward(cache, dz)?.into_buffers())
    }

    fn regularise(
        &mut self,
        cache: &Grid4dCache,
        grads: &mut [Vec<f32>],
    ) -> Result<f64, BackboneError> {
        let net = &self.field.net;
        let empty = |len: usize| vec![0f32; len];
        let buffers: Vec<usize> = net.named_params().iter().map(|(_, p)| p.len()).collect();
        let mut g = tiny_nn::Grid4dGrads {
            spatial: empty(buffers[0]),
            temporal: [empty(buffers[1]), empty(buffers[2]), empty(buffers[3])],
            attention: Vec::new(),
            temporal_mlp: Vec::new(),
            trunk: Vec::new(),
            heads: Vec::new(),
        };
        self.field.regularise(cache, &mut g)?;
        let [t0, t1, t2] = g.temporal;
        let tables = [g.spatial, t0, t1, t2];
        for (dst, src) in grads.iter_mut().zip(tables) {
            dst.iter_mut().zip(&src).for_each(|(a, b)| *a += b);
        }
        Ok(self.field.regulariser)
    }

    fn lr_scale(&self, _name: &str, _grid_lr_scale: f32) -> f32 {
        1.0
    }

    fn own_schedule(&self, name: &str) -> Option<LrSchedule> {
        Some(self.field.schedule(name))
    }
}
