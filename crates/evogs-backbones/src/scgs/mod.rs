//! The SC-GS backbone (`--backbone scgs`): sparse control points that carry the motion, after
//! Huang et al., "SC-GS: Sparse-Controlled Gaussian Splatting for Editable Dynamic Scenes"
//! (CVPR 2024; its code, `yihua7/SC-GS`, is the recipe's source).
//!
//! A network is evaluated on a few hundred control points only, each giving a translation, a
//! rotation residual, a scale residual and a local rotation at time t; every Gaussian is moved by
//! linear blend skinning of its K nearest control points with learned radial weights
//! ([`skinning`]), and the control points' trajectories are kept locally rigid by SC-GS's ARAP
//! loss ([`arap`]). The cost per Gaussian is a K-nearest search and a K-term blend instead of a
//! deep network.
//!
//! The recipe and each deliberate difference (docs/DESIGN.md §5.2d): 512 control points, K = 3,
//! the network of D-3DGS's shape (8 × 256, skip after layer 4, 10 position and 6 time
//! frequencies; SC-GS's extra time MLP is left out), He-initialised with zero heads (SC-GS: heads
//! drawn with σ = 1e-5…1e-4, so the motion starts at nearly zero too), radii
//! `exp(ρ)` from `ρ = ln(0.1 · range)` of the initial cloud, weight logits from 0, ARAP weight
//! 1e-4 (SC-GS's first stage of its schedule; held constant here). Control points are placed by
//! farthest-point sampling of the canonical Gaussians ([`Backbone::initialise`]): of the run's
//! initial ones, then again of those the static warm-up fitted when the deformation starts (in
//! place of SC-GS's 10 000-step pre-training of the control points as Gaussians, which picks them
//! by farthest-point sampling of their trajectories; `follow_densify` places them again after
//! each densification, over the Gaussians' canonical positions or, with
//! [`Placement::Trajectories`], over their trajectories under the control points as they are,
//! SC-GS's way without its pre-training). They do not learn their positions (SC-GS detaches
//! them everywhere after pre-training; a factor on their learning rate, `position_lr_scale`,
//! lets them move), and the search is in 3D (SC-GS adds 8 learned "hyper" coordinates per point
//! and Gaussian). The K nearest control points are exact at every forward, as SC-GS's search:
//! a Gaussian's are searched again only when it has moved far enough that they may have changed
//! ([`knn::NeighbourCache`]).
//!
//! EvoGS(SC-GS) (`--method evogs --backbone scgs`): this skinning as EvoGS's Φ with the evolution
//! state on every Gaussian ([`phi::ScgsPhi`], `--evolution-on gaussians`), or the evolution state
//! on the control points' own rows before the skinning ([`control_evo::ScgsControlEvo`],
//! `--evolution-on controls`).
//!
//! What it is not (yet): SC-GS's control-point densification and pruning, and its pre-training
//! stage.

pub mod arap;
pub mod control_evo;
pub mod fps;
pub mod knn;
pub mod phi;
pub mod skinning;

use std::path::Path;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use splat_core::{GaussiansView, Layout};
use strum::{Display, EnumString, IntoStaticStr, VariantNames};
use tiny_nn::{DeformCache, DeformConfig, DeformNet, Parameters, Precision, StoreMut, StoreRef};

use self::knn::Neighbours;
use self::skinning::{Controls, NODE_OUTPUT, TRANSLATION};
use crate::backbone::{Backbone, no_training_forward};
use crate::error::BackboneError;
use crate::one_word::{OneWord, unknown};

/// Most control points a run may ask for.
pub const MAX_CONTROL_POINTS: usize = 1 << 16;
/// Most neighbours per Gaussian.
pub const MAX_NEIGHBOURS: usize = 16;
/// Widest control-point network.
pub const MAX_WIDTH: usize = 2048;
/// Deepest control-point network.
pub const MAX_DEPTH: usize = 64;
/// Most frequencies of an encoding.
pub const MAX_FREQUENCIES: usize = 32;
/// Initial radius as a fraction of the initial cloud's coordinate range (SC-GS:
/// `_node_radius = log(0.1 * scene_range + 1e-7)`).
const RADIUS_FRACTION: f32 = 0.1;
/// Half-width of the time window of the ARAP loss's two times (SC-GS: `delta_t = 0.05`).
const ARAP_HALF_WINDOW: f32 = 0.025;

/// SC-GS's settings (`config.json`'s `train.scgs`; flags `--control-points` …).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ScgsSettings {
    /// Control points (SC-GS's D-NeRF command: `--node_num 512`).
    pub control_points: usize,
    /// Nearest control points per Gaussian, K (SC-GS: 3).
    pub neighbours: usize,
    /// The control-point network's hidden width (SC-GS: 256).
    pub width: usize,
    /// Its hidden layers (SC-GS: 8, the input joined again after layer 4).
    pub depth: usize,
    /// Frequencies of the control points' position encoding (SC-GS: `multires = 10`).
    pub xyz_freqs: usize,
    /// Frequencies of the time encoding (SC-GS: `t_multires = 6` for D-NeRF scenes).
    pub t_freqs: usize,
    /// Weight of the ARAP loss (SC-GS: 1e-4 in its first 5 000 steps).
    pub arap_weight: f32,
    /// Factor on the network learning rate for the control points' positions (0: they stay
    /// where they started, as in SC-GS's code).
    pub position_lr_scale: f32,
    /// Place the control points again on the Gaussians after every densification that changed
    /// them (farthest-point sampling; each new point keeps the radius and weight logit of the
    /// old point nearest to it), so that they follow the Gaussians into the moving parts a
    /// static warm-up fits poorly. Off: placed once, when the deformation starts.
    pub follow_densify: bool,
    /// What `follow_densify`'s farthest-point sampling spreads the control points over: the
    /// Gaussians' canonical positions, or their trajectories (each Gaussian's skinned position
    /// at [`TRAJECTORY_TIMES`] times, SC-GS's `samp_hyper`), which puts more control points
    /// where the motion differs. A run recorded without it placed them on canonical positions.
    pub placement: Placement,
    /// EvoGS(SC-GS) only: where the evolution state lives, on the control points
    /// ([`control_evo::ScgsControlEvo`], the default: +1.68 dB on jumpingjacks at equal CPU
    /// time, results/scgs) or on every Gaussian (the paper's wording, [`phi::ScgsPhi`]). A run
    /// recorded without it kept the state on every Gaussian, and reads so.
    #[serde(default = "EvolutionOn::recorded_before_the_choice")]
    pub evolution_on: EvolutionOn,
}

/// Where EvoGS(SC-GS) keeps its evolution state (`--evolution-on`).
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = BackboneError, parse_err_fn = unknown::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EvolutionOn {
    /// One row per Gaussian: its skinned position, rotation and scale (the paper's wording).
    Gaussians,
    /// One row per control point: its translation, rotation and scale residuals, before the
    /// skinning (a few hundred rows). The default.
    #[default]
    Controls,
}

impl EvolutionOn {
    /// What a `config.json` written before the choice existed recorded: the state on every
    /// Gaussian (the only EvoGS(SC-GS) there was).
    pub fn recorded_before_the_choice() -> Self {
        Self::Gaussians
    }
}

impl OneWord for EvolutionOn {
    const FIELD: &'static str = "scgs.evolution_on";
}

/// What the control points are spread over when they are placed again (`--control-placement`).
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = BackboneError, parse_err_fn = unknown::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Placement {
    /// The Gaussians' canonical positions (3 coordinates each). The default.
    #[default]
    Canonical,
    /// The Gaussians' trajectories: their skinned positions at [`TRAJECTORY_TIMES`] times
    /// evenly spread over `[0, 1]` (3 × 16 coordinates each; SC-GS: `samp_hyper`,
    /// `time_num = 16`, `torch.linspace(0, 1, time_num)`).
    Trajectories,
}

impl OneWord for Placement {
    const FIELD: &'static str = "scgs.placement";
}

/// Times at which a Gaussian's trajectory is sampled for [`Placement::Trajectories`] (SC-GS's
/// `time_num = 16` in `train_gui.py`'s `samp_hyper` strategy).
pub const TRAJECTORY_TIMES: usize = 16;
/// Coordinates of one trajectory.
const TRAJECTORY_DIM: usize = 3 * TRAJECTORY_TIMES;

impl Default for ScgsSettings {
    fn default() -> Self {
        Self {
            control_points: 512,
            neighbours: 3,
            width: 256,
            depth: 8,
            xyz_freqs: 10,
            t_freqs: 6,
            arap_weight: 1e-4,
            position_lr_scale: 0.0,
            follow_densify: false,
            placement: Placement::Canonical,
            evolution_on: EvolutionOn::Controls,
        }
    }
}

impl ScgsSettings {
    /// Checks every setting's range (the error names the setting, as `scgs.<field>`).
    pub fn validate(&self) -> Result<(), BackboneError> {
        let whole = |field: &str, v: usize, max: usize| {
            if (1..=max).contains(&v) {
                Ok(())
            } else {
                Err(BackboneError::config(
                    format!("scgs.{field}"),
                    format!("{v} is not in 1..={max}"),
                ))
            }
        };
        whole("control_points", self.control_points, MAX_CONTROL_POINTS)?;
        whole("neighbours", self.neighbours, MAX_NEIGHBOURS)?;
        whole("width", self.width, MAX_WIDTH)?;
        whole("depth", self.depth, MAX_DEPTH)?;
        whole("xyz_freqs", self.xyz_freqs, MAX_FREQUENCIES)?;
        whole("t_freqs", self.t_freqs, MAX_FREQUENCIES)?;
        if self.placement == Placement::Trajectories && !self.follow_densify {
            // Placed once, when the deformation starts, the trajectories are the canonical
            // positions (no motion yet): the setting would do nothing.
            return Err(BackboneError::config(
                "scgs.placement",
                "trajectories needs follow_densify (--control-follow-densify): without it the \
                 control points are placed once, before anything moves",
            ));
        }
        for (field, v) in [
            ("arap_weight", self.arap_weight),
            ("position_lr_scale", self.position_lr_scale),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(BackboneError::config(
                    format!("scgs.{field}"),
                    format!("{v} is not a finite number >= 0"),
                ));
            }
        }
        Ok(())
    }
}

/// The learnable parts: the control-point network and the control points' shape.
pub(crate) struct ScgsParams {
    net: DeformNet,
    positions: Vec<[f32; 3]>,
    log_radii: Vec<f32>,
    weight_logits: Vec<f32>,
}

/// Names of the control points' buffers, after the network's.
const POSITIONS: &str = "controls.position";
const LOG_RADII: &str = "controls.log_radius";
const WEIGHT_LOGITS: &str = "controls.weight_logit";

impl Parameters for ScgsParams {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        let mut out: Vec<(String, StoreRef<'_>)> = self
            .net
            .named_params()
            .into_iter()
            .map(|(n, s)| (format!("net.{n}"), s))
            .collect();
        out.push((
            POSITIONS.into(),
            StoreRef::F32(self.positions.as_flattened()),
        ));
        out.push((LOG_RADII.into(), StoreRef::F32(&self.log_radii)));
        out.push((WEIGHT_LOGITS.into(), StoreRef::F32(&self.weight_logits)));
        out
    }

    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        let mut out: Vec<(String, StoreMut<'_>)> = self
            .net
            .named_params_mut()
            .into_iter()
            .map(|(n, s)| (format!("net.{n}"), s))
            .collect();
        out.push((
            POSITIONS.into(),
            StoreMut::F32(self.positions.as_flattened_mut()),
        ));
        out.push((LOG_RADII.into(), StoreMut::F32(&mut self.log_radii)));
        out.push((WEIGHT_LOGITS.into(), StoreMut::F32(&mut self.weight_logits)));
        out
    }
}

impl ScgsParams {
    /// The network and control points of `settings`, the points spread over `[-h, h]³` until
    /// placed on the Gaussians.
    fn new(settings: &ScgsSettings, half_extent: f32, seed: u64) -> Result<Self, BackboneError> {
        settings.validate()?;
        let net = DeformNet::with_outputs(Self::net_config(settings, seed), NODE_OUTPUT)?;
        let m = settings.control_points;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5C65_C0DE);
        let h = half_extent.abs().max(f32::MIN_POSITIVE);
        let cube: Vec<[f32; 3]> = (0..m)
            .map(|_| std::array::from_fn(|_| rng.random_range(-h..=h)))
            .collect();
        let mut params = Self {
            net,
            positions: vec![[0.0; 3]; m],
            log_radii: vec![0.0; m],
            weight_logits: vec![0.0; m],
        };
        params.place(&cube, seed);
        Ok(params)
    }

    /// The control points' network [`ScgsParams::new`] builds.
    fn net_config(settings: &ScgsSettings, seed: u64) -> DeformConfig {
        DeformConfig {
            width: settings.width,
            depth: settings.depth,
            skip_after: (settings.depth > 4).then_some(settings.depth / 2),
            xyz_freqs: settings.xyz_freqs,
            t_freqs: settings.t_freqs,
            init: tiny_nn::Init::He,
            zero_heads: true,
            precision: Precision::F32,
            seed: seed ^ 0x5C65_0000,
        }
    }

    /// The parameters [`ScgsParams::new`] allocates (the network's, and per control point its
    /// position, log radius and weight logit), without allocating them.
    pub(crate) fn param_count(settings: &ScgsSettings, seed: u64) -> Result<usize, BackboneError> {
        settings.validate()?;
        let net = Self::net_config(settings, seed).param_count(NODE_OUTPUT)?;
        settings
            .control_points
            .checked_mul(3 + 1 + 1)
            .and_then(|points| points.checked_add(net))
            .ok_or_else(|| BackboneError::config("scgs.control_points", "too many parameters"))
    }

    fn controls(&self) -> Controls<'_> {
        Controls {
            positions: &self.positions,
            log_radii: &self.log_radii,
            weight_logits: &self.weight_logits,
        }
    }

    /// Control points at `points` (picked by farthest-point sampling), radii from the points'
    /// coordinate range, weight logits 0.
    fn place(&mut self, points: &[[f32; 3]], seed: u64) {
        let m = self.positions.len();
        let picked = fps::farthest_points(points, m, seed);
        if picked.is_empty() {
            return;
        }
        for (p, i) in self.positions.iter_mut().zip(picked) {
            *p = points[i];
        }
        let (lo, hi) = points
            .iter()
            .flatten()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        let radius = (RADIUS_FRACTION * (hi - lo) + 1e-7).ln();
        self.log_radii.fill(radius);
        self.weight_logits.fill(0.0);
    }
}

impl ScgsParams {
    /// The network's outputs at every control point at `time` (M × [`NODE_OUTPUT`]), its
    /// activations in `cache`.
    fn node_outputs(&self, time: f32, cache: &mut DeformCache) -> Result<Vec<f32>, BackboneError> {
        let m = self.positions.len();
        Ok(self
            .net
            .forward_into(self.positions.as_flattened(), &vec![time; m], m, cache)?)
    }

    /// The control points' positions at `time` (canonical + the network's translation).
    fn controls_at(&self, time: f32) -> Result<Vec<[f32; 3]>, BackboneError> {
        let nodes = self.node_outputs(time, &mut DeformCache::default())?;
        Ok(moved(&self.positions, &nodes))
    }

    /// Skins `means` with the control points' outputs `nodes` into `out` (N × [`skinning::ROW`]),
    /// their `k` nearest control points found through `cache`; returns those neighbours (for
    /// the backward).
    fn skin(
        &self,
        cache: &mut knn::NeighbourCache,
        k: usize,
        means: &[[f32; 3]],
        nodes: &[f32],
        out: &mut Vec<f32>,
    ) -> Result<Neighbours, BackboneError> {
        let neighbours = cache.update(&self.positions, means, k)?.clone();
        skinning::skin_into(means, &neighbours, self.controls(), nodes, out);
        Ok(neighbours)
    }
}

impl ScgsParams {
    /// Each Gaussian's trajectory under the control points as they are: its position skinned
    /// with `k` neighbours at [`TRAJECTORY_TIMES`] times evenly spread over `[0, 1]`, one point
    /// of [`TRAJECTORY_DIM`] coordinates per Gaussian.
    fn trajectories(
        &self,
        means: &[[f32; 3]],
        k: usize,
    ) -> Result<Vec<[f32; TRAJECTORY_DIM]>, BackboneError> {
        let mut search = knn::NeighbourCache::default();
        let neighbours = search.update(&self.positions, means, k)?;
        let mut out = vec![[0f32; TRAJECTORY_DIM]; means.len()];
        let (mut net, mut rows) = (DeformCache::default(), Vec::new());
        for j in 0..TRAJECTORY_TIMES {
            let time = j as f32 / (TRAJECTORY_TIMES - 1) as f32;
            let nodes = self.node_outputs(time, &mut net)?;
            skinning::skin_into(means, neighbours, self.controls(), &nodes, &mut rows);
            for ((o, row), x) in out
                .iter_mut()
                .zip(rows.chunks_exact(skinning::ROW))
                .zip(means)
            {
                for c in 0..3 {
                    // A skinned row's position is the displacement from the canonical mean.
                    o[3 * j + c] = x[c] + row[c];
                }
            }
        }
        Ok(out)
    }

    /// Places the control points again on `points` (farthest-point sampling over what
    /// `placement` names, with `k` neighbours per Gaussian for its trajectories), each keeping
    /// the radius and weight logit of the old control point nearest to it; returns those old
    /// points, one per new point (none when there is nothing to place on).
    fn follow(
        &mut self,
        points: &[[f32; 3]],
        seed: u64,
        placement: Placement,
        k: usize,
    ) -> Result<Vec<u32>, BackboneError> {
        let m = self.positions.len();
        let picked = match placement {
            Placement::Canonical => fps::farthest_points(points, m, seed),
            Placement::Trajectories => {
                fps::farthest_points(&self.trajectories(points, k)?, m, seed)
            }
        };
        if picked.is_empty() {
            return Ok(Vec::new());
        }
        let mut parents = Vec::with_capacity(picked.len());
        let old = std::mem::take(&mut self.positions);
        let (radii, logits) = (self.log_radii.clone(), self.weight_logits.clone());
        self.positions = picked.iter().map(|&i| points[i]).collect();
        for (k, p) in self.positions.iter().enumerate() {
            let nearest = old
                .iter()
                .enumerate()
                .map(|(j, q)| (knn::dist2_between(p, q), j))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
                .map_or(k, |(_, j)| j);
            self.log_radii[k] = radii[nearest];
            self.weight_logits[k] = logits[nearest];
            parents.push(nearest as u32);
        }
        Ok(parents)
    }

    /// The gradients of every buffer (network, positions, log radii, weight logits) from the
    /// skinned rows' gradient `d_rows` (N × [`skinning::ROW`]) of a forward that skinned `means`
    /// with `nodes` (its network cache `net`); the positions' gradient only when `want_positions`
    /// (else zeros: they do not move, and the network's input pass is spared).
    fn gradients(
        &self,
        means: &[[f32; 3]],
        neighbours: &Neighbours,
        nodes: &[f32],
        net: &DeformCache,
        d_rows: &[f32],
        want_positions: bool,
    ) -> Result<Vec<Vec<f32>>, BackboneError> {
        let skin = skinning::skin_backward(means, neighbours, self.controls(), nodes, d_rows);
        self.node_gradients(net, skin, want_positions)
    }

    /// [`ScgsParams::gradients`] from the control points' side: the network's backward of
    /// `skin.nodes` (M × [`NODE_OUTPUT`], the gradient of its outputs, which a caller may have
    /// changed) joined with the skinning's gradients of the control points' shape.
    fn node_gradients(
        &self,
        net: &DeformCache,
        skin: skinning::SkinGrads,
        want_positions: bool,
    ) -> Result<Vec<Vec<f32>>, BackboneError> {
        let g = self.net.backward(net, &skin.nodes, want_positions)?;
        let mut d_positions = skin.positions;
        match &g.positions {
            Some(p) => add_into(&mut d_positions, p),
            None => d_positions.fill(0.0),
        }
        Ok(vec![g.mlp, d_positions, skin.log_radii, skin.weight_logits])
    }

    /// SC-GS's ARAP loss, weighted by `lambda`, between the control points at a forward's time
    /// (its outputs `nodes`, network cache `net`) and at `partner`: adds its gradient to `grads`
    /// (in [`ScgsParams::gradients`]' order; to the positions only when `want_positions`) and
    /// returns its weighted value (0 when off or with fewer than two control points).
    ///
    /// A caller that runs the network's backward at the forward's time anyway saves one pass
    /// with [`ScgsParams::arap_terms`], [`ArapTerms::add_to_nodes`] and
    /// [`ScgsParams::finish_arap`] instead (the backward is linear in its output gradient).
    fn add_arap(
        &self,
        lambda: f32,
        partner: f32,
        nodes: &[f32],
        net: &DeformCache,
        want_positions: bool,
        grads: &mut [Vec<f32>],
    ) -> Result<f64, BackboneError> {
        let terms = self.arap_terms(lambda, partner, nodes)?;
        if let Some(terms) = &terms {
            let mut d_nodes = vec![0f32; self.positions.len() * NODE_OUTPUT];
            terms.add_to_nodes(&mut d_nodes);
            let g = self.net.backward(net, &d_nodes, want_positions)?;
            add_into(&mut grads[0], &g.mlp);
            if let Some(p) = &g.positions {
                add_into(&mut grads[1], p);
            }
        }
        self.finish_arap(terms, want_positions, grads)
    }

    /// SC-GS's ARAP loss, weighted by `lambda`, between the control points at a forward's time
    /// (its outputs `nodes`) and at `partner`, with its gradients not yet spent; `None` when off
    /// or with fewer than two control points.
    fn arap_terms(
        &self,
        lambda: f32,
        partner: f32,
        nodes: &[f32],
    ) -> Result<Option<ArapTerms>, BackboneError> {
        if lambda == 0.0 || self.positions.len() < 2 {
            return Ok(None);
        }
        let mut partner_net = DeformCache::default();
        let nodes1 = self.node_outputs(partner, &mut partner_net)?;
        let a = arap::arap(
            &moved(&self.positions, nodes),
            &moved(&self.positions, &nodes1),
        )?;
        let scale = |d: Vec<f32>| d.into_iter().map(|v| lambda * v).collect::<Vec<f32>>();
        Ok(Some(ArapTerms {
            loss: f64::from(lambda) * a.loss,
            d_first: scale(a.d_first),
            d_second: scale(a.d_second),
            partner_net,
        }))
    }

    /// Spends what [`ArapTerms::add_to_nodes`] did not: the moved positions' gradient on the
    /// canonical positions (when `want_positions`) and the network's backward at the partner
    /// time, into `grads`; returns the weighted loss (0 without terms: the loss off).
    fn finish_arap(
        &self,
        terms: Option<ArapTerms>,
        want_positions: bool,
        grads: &mut [Vec<f32>],
    ) -> Result<f64, BackboneError> {
        let Some(terms) = terms else {
            return Ok(0.0);
        };
        let m = self.positions.len();
        if want_positions {
            add_into(&mut grads[1], &terms.d_first);
            add_into(&mut grads[1], &terms.d_second);
        }
        let mut d_nodes = vec![0f32; m * NODE_OUTPUT];
        for (row, d) in d_nodes
            .chunks_exact_mut(NODE_OUTPUT)
            .zip(terms.d_second.chunks_exact(3))
        {
            row[..3].copy_from_slice(d);
        }
        let g = self
            .net
            .backward(&terms.partner_net, &d_nodes, want_positions)?;
        add_into(&mut grads[0], &g.mlp);
        if let Some(p) = &g.positions {
            add_into(&mut grads[1], p);
        }
        Ok(terms.loss)
    }
}

/// SC-GS's weighted ARAP loss between a forward's time and its partner, its gradients with
/// respect to the moved control points at both times (M × 3, weight included) not yet spent.
struct ArapTerms {
    /// The weighted loss.
    loss: f64,
    /// Its gradient on the control points moved to the forward's time.
    d_first: Vec<f32>,
    /// Its gradient on the control points moved to the partner time.
    d_second: Vec<f32>,
    /// The network's activations at the partner time.
    partner_net: DeformCache,
}

impl ArapTerms {
    /// Adds the loss's gradient at the forward's time to the network's output gradient
    /// `d_nodes` (M × [`NODE_OUTPUT`]; the translation is its first three columns), so that
    /// one backward at that time carries both.
    fn add_to_nodes(&self, d_nodes: &mut [f32]) {
        for (row, d) in d_nodes
            .chunks_exact_mut(NODE_OUTPUT)
            .zip(self.d_first.chunks_exact(3))
        {
            add_into(&mut row[..3], d);
        }
    }
}

/// What the backward pass needs of the last training forward.
struct Cache {
    time: f32,
    means: Vec<[f32; 3]>,
    neighbours: Neighbours,
    nodes: Vec<f32>,
    net: DeformCache,
}

/// SC-GS's sparse control points as a backbone (module docs).
pub struct ScgsBackbone {
    settings: ScgsSettings,
    seed: u64,
    params: ScgsParams,
    cache: Option<Cache>,
    /// The weighted ARAP loss of the last backward.
    arap_loss: f64,
    /// The K nearest control points, searched again only where they may have changed.
    neighbours: knn::NeighbourCache,
}

impl ScgsBackbone {
    /// The backbone of `settings`, its control points spread over the cube `[-h, h]³` until
    /// [`Backbone::initialise`] places them on the run's Gaussians.
    pub fn new(
        settings: &ScgsSettings,
        half_extent: f32,
        seed: u64,
    ) -> Result<Self, BackboneError> {
        let params = ScgsParams::new(settings, half_extent, seed)?;
        Ok(Self {
            settings: *settings,
            seed,
            params,
            cache: None,
            arap_loss: 0.0,
            neighbours: knn::NeighbourCache::default(),
        })
    }

    /// The control points' canonical positions.
    pub fn control_positions(&self) -> &[[f32; 3]] {
        &self.params.positions
    }

    /// The control points' radii `exp(ρ)`.
    pub fn control_radii(&self) -> Vec<f32> {
        self.params.log_radii.iter().map(|r| r.exp()).collect()
    }

    /// The control points' positions at `time` (canonical + the network's translation).
    pub fn controls_at(&self, time: f32) -> Result<Vec<[f32; 3]>, BackboneError> {
        self.params.controls_at(time)
    }

    fn learns_positions(&self) -> bool {
        self.settings.position_lr_scale > 0.0
    }
}

/// The partner time of ARAP's pair for a step at `time`: within ±[`ARAP_HALF_WINDOW`], drawn
/// from the run's seed and the time (the same on a resumed run), in `[0, 1]`.
fn arap_partner(seed: u64, time: f32) -> f32 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ u64::from(time.to_bits()) ^ 0xA7A9);
    let delta = rng.random_range(-ARAP_HALF_WINDOW..=ARAP_HALF_WINDOW);
    (time + delta).clamp(0.0, 1.0)
}

/// The factor on the network schedule for the buffer `name`: the control points' positions at
/// `position_lr_scale`, every other buffer at 1.
fn position_lr_scale(name: &str, settings: &ScgsSettings) -> f32 {
    if name == POSITIONS {
        settings.position_lr_scale
    } else {
        1.0
    }
}

/// The columns of a control point's outputs (equally of a skinned row: [`skinning::ROW`]'s
/// first ten columns are the same) that EvoGS's `layout` keeps, in its order; opacity and colour
/// are refused (SC-GS deforms neither).
fn evolved_columns(layout: Layout) -> Result<Vec<usize>, BackboneError> {
    if layout.opacity || layout.colour {
        return Err(BackboneError::config(
            "evogs.components",
            format!(
                "`{layout}`: SC-GS deforms position, rotation and scale only; use \
                 --components pos,rot,scale (or a part of it)"
            ),
        ));
    }
    Ok([
        (layout.position, skinning::TRANSLATION),
        (layout.rotation, skinning::ROTATION),
        (layout.scale, skinning::SCALE),
    ]
    .into_iter()
    .filter(|(on, _)| *on)
    .flat_map(|(_, r)| r)
    .collect())
}

/// Positions plus the translation columns of `nodes`.
fn moved(positions: &[[f32; 3]], nodes: &[f32]) -> Vec<[f32; 3]> {
    positions
        .iter()
        .zip(nodes.chunks_exact(NODE_OUTPUT))
        .map(|(p, n)| {
            let t = &n[TRANSLATION];
            [p[0] + t[0], p[1] + t[1], p[2] + t[2]]
        })
        .collect()
}

impl Backbone for ScgsBackbone {
    fn name(&self) -> &'static str {
        "scgs"
    }

    fn control_points_at(&mut self, time: f32) -> Result<Option<Vec<[f32; 3]>>, BackboneError> {
        self.controls_at(time).map(Some)
    }

    fn initialise(&mut self, canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        self.params.place(canonical.means, self.seed);
        Ok(())
    }

    fn gaussians_changed(&mut self, canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        if self.settings.follow_densify {
            self.params.follow(
                canonical.means,
                self.seed,
                self.settings.placement,
                self.settings.neighbours,
            )?;
        }
        Ok(())
    }

    fn forward_into(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), BackboneError> {
        let mut net = self.cache.take().map(|c| c.net).unwrap_or_default();
        let nodes = self.params.node_outputs(time, &mut net)?;
        let neighbours = self.params.skin(
            &mut self.neighbours,
            self.settings.neighbours,
            canonical.means,
            &nodes,
            out,
        )?;
        if training {
            self.cache = Some(Cache {
                time,
                means: canonical.means.to_vec(),
                neighbours,
                nodes,
                net,
            });
        }
        Ok(())
    }

    fn backward_into(
        &mut self,
        d_deform: &[f32],
        out: &mut Vec<Vec<f32>>,
    ) -> Result<(), BackboneError> {
        let cache = self.cache.take().ok_or_else(no_training_forward)?;
        let result = self.backward_cached(&cache, d_deform);
        self.cache = Some(cache);
        *out = result?;
        Ok(())
    }

    fn params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.params.named_params()
    }

    fn params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.params.named_params_mut()
    }

    fn lr_scale(&self, name: &str) -> f32 {
        position_lr_scale(name, &self.settings)
    }

    fn loss_terms(&self) -> f64 {
        self.arap_loss
    }

    fn save(&self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::save(path, &self.params)?)
    }

    fn load(&mut self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::load(path, &mut self.params)?)
    }
}

impl ScgsBackbone {
    /// The gradients of every parameter buffer (in [`Backbone::params`]'s order) from the rows'
    /// gradient and the ARAP loss, for the forward of `cache`.
    fn backward_cached(
        &mut self,
        cache: &Cache,
        d_deform: &[f32],
    ) -> Result<Vec<Vec<f32>>, BackboneError> {
        let expected = cache.means.len() * skinning::ROW;
        if d_deform.len() != expected {
            return Err(BackboneError::config(
                "scgs",
                format!("{} row gradients for {expected} values", d_deform.len()),
            ));
        }
        let want = self.learns_positions();
        let arap = self.params.arap_terms(
            self.settings.arap_weight,
            arap_partner(self.seed, cache.time),
            &cache.nodes,
        )?;
        let mut skin = skinning::skin_backward(
            &cache.means,
            &cache.neighbours,
            self.params.controls(),
            &cache.nodes,
            d_deform,
        );
        // ARAP's gradient at the forward's time rides the skinning's backward pass.
        if let Some(terms) = &arap {
            terms.add_to_nodes(&mut skin.nodes);
        }
        let mut grads = self.params.node_gradients(&cache.net, skin, want)?;
        self.arap_loss = self.params.finish_arap(arap, want, &mut grads)?;
        Ok(grads)
    }
}

fn add_into(a: &mut [f32], b: &[f32]) {
    for (x, y) in a.iter_mut().zip(b) {
        *x += y;
    }
}
