//! The Grid4D backbone (`--backbone grid4d`): its 4D decomposed hash-grid field
//! ([`tiny_nn::Grid4dNet`]) with its smoothness regulariser, for the baseline and as EvoGS's Φ.
//!
//! The recipe (`JiaweiXu8/Grid4D`, D-NeRF settings `arguments/dnerf/*.py`, `arguments/__init__.py`,
//! `scene/deform_model.py`, `train.py`; docs/DESIGN.md §5.2c cites each constant):
//! - the field: [`tiny_nn::Grid4dConfig::dnerf`] over `[-bound, bound]³` with Grid4D's
//!   `bound = 1.6` for its D-NeRF scenes, whose initial cube is 3DGS's ±1.3: here
//!   `bound = 1.6 / 1.3 · h` for the run's initial cube `[-h, h]³` ([`Grid4dRun::bound`]; 1.6 in every
//!   preset); deformation of position (Grid4D's rigid warp), rotation and scale;
//! - the smoothness regulariser on 10 % of the Gaussians every training step, spatial and
//!   temporal weights 0.5 (`lambda_spatial_tv`, `lambda_temporal_tv`; `reg_after_densify` is
//!   off in Grid4D's D-NeRF settings, so it runs from the first deformed step);
//! - learning rates: the decoder at `position_lr_init · network_lr_scale` = 1.6e-4 · 5 decaying
//!   to `position_lr_final` = 1.6e-6 ([`NETWORK_LR_SCALE`]; the trainer's network schedule, the
//!   same as D-3DGS's), the hash tables at `position_lr_init · grid_lr_scale` = 1.6e-4 · 50
//!   decaying to 1.6e-6 · 50 ([`GRID_LR_SCALE`]), both over the run's network decay length
//!   (Grid4D: `deform_lr_max_steps = 45 000` of its runs);
//! - the static warm-up (`warm_up = 3 000` in Grid4D, as D-3DGS) is the trainer's.
//!
//! Sizes ([`Grid4dRun`], set per preset by the trainer; the one departure from Grid4D's
//! constants, since a CPU runs dense Adam over every table entry each step): the decoder width is
//! the run's network width ([`crate::NetSettings::width`]: 256 in the `paper` preset, as Grid4D;
//! 64 in `cpu` and `dnerf`; 32 in `tiny`), and the tables hold at most `2^log2_table` entries per
//! level (19 in `paper`, as Grid4D; 15 in `cpu` and `dnerf`; 12 in `tiny`).
//!
//! EvoGS(Grid4D) ([`crate::grid4d_phi::Grid4dPhi`], its own module): Φ is this field at half the run's width with one head per
//! evolution component (zero-initialised, so Φ's first observation is 0 as EvoGS(D-3DGS)'s Φ),
//! its smoothness regulariser added to Φ's gradients; [`crate::EvoBackbone`] wraps it exactly as
//! it wraps EvoGS(D-3DGS)'s tri-plane Φ.

use std::path::Path;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_core::GaussiansView;
use tiny_nn::{
    ExponentialLr, Grid4dCache, Grid4dConfig, Grid4dHead, Grid4dNet, LrSchedule, Parameters,
    StoreMut, StoreRef, is_grid4d_table,
};

use crate::backbone::{Backbone, fill_inputs, no_training_forward};
use crate::error::BackboneError;

/// Grid4D's `network_lr_scale`: the decoder's initial lr is `position_lr_init` times this.
pub const NETWORK_LR_SCALE: f32 = 5.0;
/// Grid4D's `grid_lr_scale`: both ends of the tables' lr are `position_lr_*` times this.
pub const GRID_LR_SCALE: f32 = 50.0;
/// Grid4D's `bound` for its D-NeRF scenes.
pub const GRID4D_BOUND: f32 = 1.6;
/// 3DGS's initial cube half-extent for D-NeRF scenes, to which [`GRID4D_BOUND`] belongs.
const DNERF_INIT_HALF_EXTENT: f32 = 1.3;

/// The trainer's learning-rate settings the Grid4D schedules are made from (its 3DGS position
/// rate and the network's decay length and factor).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid4dLr {
    /// `position_lr_init` (1.6e-4).
    pub position_init: f32,
    /// `position_lr_final` (1.6e-6).
    pub position_final: f32,
    /// `position_lr_delay_mult` (0.01).
    pub delay_mult: f32,
    /// Steps of the exponential decay (the run's network decay length).
    pub max_steps: u64,
    /// Factor on both ends of both schedules (the trainer's `deform_scale`, 1 by default).
    pub scale: f32,
}

impl Grid4dLr {
    /// The hash tables' schedule (Grid4D's `grid_lr_scheduler`): `position_init · 50` decaying
    /// to `position_final · 50`.
    pub fn grid(&self) -> LrSchedule {
        self.schedule(GRID_LR_SCALE, GRID_LR_SCALE)
    }

    /// The decoder's schedule (Grid4D's `network_lr_scheduler`): `position_init · 5` decaying
    /// to `position_final`.
    pub fn decoder(&self) -> LrSchedule {
        self.schedule(NETWORK_LR_SCALE, 1.0)
    }

    fn schedule(&self, init: f32, end: f32) -> LrSchedule {
        LrSchedule::Exponential(ExponentialLr {
            lr_init: self.position_init * init * self.scale,
            lr_final: self.position_final * end * self.scale,
            delay_steps: 0,
            delay_mult: self.delay_mult,
            max_steps: self.max_steps,
        })
    }
}

/// What a Grid4D backbone takes of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid4dRun {
    /// Decoder width of the baseline's field (Φ takes half).
    pub width: usize,
    /// `log2` of the most entries of a level's table.
    pub log2_table: u32,
    /// Half extent `h` of the initial cube `[-h, h]³`.
    pub half_extent: f32,
    /// The learning rates.
    pub lr: Grid4dLr,
    /// The run's seed.
    pub seed: u64,
}

impl Grid4dRun {
    /// The box half-width of the field: Grid4D's 1.6 relative to the D-NeRF initial cube ±1.3.
    pub fn bound(&self) -> f32 {
        GRID4D_BOUND / DNERF_INIT_HALF_EXTENT * self.half_extent
    }

    /// Grid4D's field for the run: the D-NeRF recipe at this table size, decoder `width`, the
    /// given heads.
    pub fn field(
        &self,
        width: usize,
        heads: Vec<Grid4dHead>,
        zero_heads: bool,
        seed: u64,
    ) -> Grid4dConfig {
        let mut c = Grid4dConfig::dnerf(self.bound(), seed);
        c.spatial.log2_table = self.log2_table;
        c.temporal.log2_table = self.log2_table;
        c.width = width.max(1);
        c.heads = heads;
        c.zero_heads = zero_heads;
        c
    }
}

/// The field with what its training steps need: the seed of the regulariser's samples, the
/// schedules and the last regulariser value. Shared by the baseline ([`Grid4dBackbone`]) and Φ
/// ([`crate::grid4d_phi::Grid4dPhi`]).
///
/// The regulariser's random rows and moves are drawn from a stream seeded by the run's seed and a
/// hash of the step's inputs (every canonical mean and the time, as the encoder saw them): a pure
/// function of the training state, so a resumed run draws what an uninterrupted one would
/// (DESIGN §7.6), with no counter to save.
pub(crate) struct Field {
    pub(crate) net: Grid4dNet,
    seed: u64,
    grid: LrSchedule,
    decoder: LrSchedule,
    pub(crate) regulariser: f64,
}

impl Field {
    pub(crate) fn new(net: Grid4dNet, lr: &Grid4dLr, seed: u64) -> Self {
        Self {
            net,
            seed,
            grid: lr.grid(),
            decoder: lr.decoder(),
            regulariser: 0.0,
        }
    }

    /// `m` distinct rows of `rows`, uniformly (a partial Fisher–Yates shuffle, as `randperm[:m]`).
    fn sample(rng: &mut ChaCha8Rng, rows: usize, m: usize) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..rows).collect();
        for i in 0..m.min(rows) {
            let j = rng.random_range(i..rows);
            idx.swap(i, j);
        }
        idx.truncate(m.min(rows));
        idx
    }

    /// Adds the smoothness regulariser of the forward `cache` to `grads`; records its value.
    pub(crate) fn regularise(
        &mut self,
        cache: &Grid4dCache,
        grads: &mut tiny_nn::Grid4dGrads,
    ) -> Result<(), BackboneError> {
        let rows = cache.rows();
        let m = self.net.config().smoothness.samples(rows);
        // FNV-1a over the inputs' bits, mixed with the seed.
        let hash = cache
            .encoder_inputs()
            .iter()
            .fold(0xCBF2_9CE4_8422_2325u64, |h, v| {
                (h ^ v.to_bits() as u64).wrapping_mul(0x0100_0000_01B3)
            });
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ hash);
        let spatial = Self::sample(&mut rng, rows, m);
        let spatial_jitter: Vec<f32> = (0..m * 3).map(|_| rng.random_range(-1.0f32..1.0)).collect();
        let temporal = Self::sample(&mut rng, rows, m);
        let temporal_jitter: Vec<f32> =
            (0..m * 4).map(|_| rng.random_range(-1.0f32..1.0)).collect();
        self.regulariser = self.net.smoothness(
            cache,
            &spatial,
            &spatial_jitter,
            &temporal,
            &temporal_jitter,
            grads,
        )?;
        Ok(())
    }

    pub(crate) fn schedule(&self, name: &str) -> LrSchedule {
        if is_grid4d_table(name) {
            self.grid
        } else {
            self.decoder
        }
    }
}

/// The Grid4D backbone of the baseline.
pub struct Grid4dBackbone {
    field: Field,
    cache: Option<Grid4dCache>,
}

impl Grid4dBackbone {
    /// Grid4D's field for `run` at its width, initialised from its seed.
    pub fn new(run: &Grid4dRun) -> Result<Self, BackboneError> {
        let seed = run.seed ^ 0x6D4D_0000;
        let net = Grid4dNet::new(Self::config(run))?;
        Ok(Self {
            field: Field::new(net, &run.lr, seed ^ 0x5EED),
            cache: None,
        })
    }

    /// The field.
    pub fn net(&self) -> &Grid4dNet {
        &self.field.net
    }

    /// The field [`Grid4dBackbone::new`] builds.
    pub(crate) fn config(run: &Grid4dRun) -> tiny_nn::Grid4dConfig {
        run.field(
            run.width,
            vec![
                Grid4dHead::Position,
                Grid4dHead::Rotation,
                Grid4dHead::Scale,
            ],
            false,
            run.seed ^ 0x6D4D_0000,
        )
    }
}

impl Backbone for Grid4dBackbone {
    fn name(&self) -> &'static str {
        "grid4d"
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
        let mut cache = self.cache.take().unwrap_or_default();
        let geometry = self
            .field
            .net
            .forward_into(&positions, &times, n, &mut cache)?;
        if training {
            self.cache = Some(cache);
        }
        // The field's heads are the rows: position, rotation, scale (`Layout::GEOMETRY`).
        *out = geometry;
        Ok(())
    }

    fn backward_into(
        &mut self,
        d_deform: &[f32],
        out: &mut Vec<Vec<f32>>,
    ) -> Result<(), BackboneError> {
        let cache = self.cache.take().ok_or_else(no_training_forward)?;
        let mut g = self.field.net.backward(&cache, d_deform)?;
        self.field.regularise(&cache, &mut g)?;
        self.cache = Some(cache);
        *out = g.into_buffers();
        Ok(())
    }

    fn params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.field.net.named_params()
    }

    fn params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.field.net.named_params_mut()
    }

    fn own_schedule(&self, name: &str) -> Option<LrSchedule> {
        Some(self.field.schedule(name))
    }

    fn loss_terms(&self) -> f64 {
        self.field.regulariser
    }

    fn save(&self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::save(path, &self.field.net)?)
    }

    fn load(&mut self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::load(path, &mut self.field.net)?)
    }
}
