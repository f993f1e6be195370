//! EvoGS(SC-GS) with the evolution state on the control points
//! (`--method evogs --backbone scgs --evolution-on controls`; DESIGN §5.2d).
//!
//! The observation `z` is the control-point network's output at the M control points (the
//! columns of their translation `T`, rotation residual `Q` and scale residual `S` that EvoGS's
//! components keep: position → `T`, rotation → `Q`, scale → `S`), evo-state evolves those M rows
//! (buffer, prior, residual memory and Ψ, a few hundred rows per frame), and the corrected rows
//! take the place of the network's columns before the Gaussians are skinned
//! ([`super::skinning`]); the local rotation `L` and the columns EvoGS does not keep go to the
//! skinning as the network gives them. The gradient comes back the same way: the skinning's
//! gradient of the control points' rows, evo-state's backward on the evolved columns
//! (L_render + λ1 L_sup + λ2 L_prior, every row weighted 1: a control point has no opacity),
//! and the network's backward of the whole row. SC-GS's ARAP loss stays on the network's own
//! trajectories (its regulariser).
//!
//! The state is per control point, not per Gaussian: densification leaves it alone; placing the
//! control points again (`follow_densify`) gives each new point the rows of the old point
//! nearest to it (the radius and weight rule), a fresh placement ([`Backbone::initialise`])
//! starts it empty. The per-Gaussian reports (motion statistics, residual cues of the
//! uncertainty-aware trigger) have nothing to read; the deformation-aware densification reads
//! the skinned rows.
//!
//! What it is not: the paper's wording (the state on every Gaussian, [`super::phi::ScgsPhi`] in
//! [`crate::EvoBackbone`], `--evolution-on gaussians`).

use std::path::Path;

use densify::{Deformation, PerGaussian};
use evo_state::{Backward, EvoState, HistoryMode, Step};
use splat_core::{GaussiansView, Layout, RowPlan};
use tiny_nn::{DeformCache, LrSchedule, Parameters, StoreMut, StoreRef};

use super::knn::{self, Neighbours};
use super::skinning::{self, NODE_OUTPUT, ROW};
use super::{ScgsParams, ScgsSettings, add_into, arap_partner, evolved_columns, moved};
use crate::backbone::{Backbone, DensifyCues, GainStats, PerGaussianState, no_training_forward};
use crate::error::BackboneError;
use crate::evo_backbone::{
    empty_state, load_state_file, save_state_file, sized_state, unsized_state,
};
use crate::evo_settings::EvoSettings;

/// What the last training forward kept for its backward.
struct Training {
    time: f32,
    means: Vec<[f32; 3]>,
    neighbours: Neighbours,
    /// The network's outputs (M × [`NODE_OUTPUT`]).
    nodes: Vec<f32>,
    /// The same with the evolved columns corrected: what the Gaussians were skinned with.
    blended: Vec<f32>,
    net: DeformCache,
    /// The observation: the evolved columns of `nodes` (M × D).
    z: Vec<f32>,
    step: Step,
    /// The network's caches at the re-queried history times (history `requery` only).
    history: Vec<(f32, DeformCache)>,
    /// The skinned rows (N × [`ROW`]), for deformation-aware densification.
    rows: Vec<f32>,
    committed: bool,
}

/// EvoGS(SC-GS) with the evolution state on the control points (module docs).
pub struct ScgsControlEvo {
    settings: ScgsSettings,
    evogs: EvoSettings,
    seed: u64,
    params: ScgsParams,
    /// Columns of a control point's outputs that evolve, in the evolution layout's order.
    columns: Vec<usize>,
    evo: EvoState,
    /// Whether `evo` was built for the run's frames (or loaded).
    ready: bool,
    training: Option<Training>,
    backward: Option<Backward>,
    /// The weighted ARAP loss of the last backward.
    arap_loss: f64,
    neighbours: knn::NeighbourCache,
}

/// Name prefix of the control points' network and shape (as EvoGS's Φ).
const PHI: &str = "phi.";
/// Name of Ψ's buffer.
const PSI: &str = "psi";

/// The columns `columns` of every `width`-wide row of `rows`.
fn gather(rows: &[f32], width: usize, columns: &[usize]) -> Vec<f32> {
    rows.chunks_exact(width)
        .flat_map(|r| columns.iter().map(move |&c| r[c]))
        .collect()
}

/// Writes `values` (rows of `columns.len()`) into the columns `columns` of `rows`.
fn scatter(rows: &mut [f32], width: usize, columns: &[usize], values: &[f32]) {
    for (row, v) in rows
        .chunks_exact_mut(width)
        .zip(values.chunks_exact(columns.len().max(1)))
    {
        for (&c, &x) in columns.iter().zip(v) {
            row[c] = x;
        }
    }
}

impl ScgsControlEvo {
    /// EvoGS(SC-GS) of SC-GS's `settings` and EvoGS's `evogs` (its components must be
    /// geometric), the control points spread over `[-h, h]³` until placed on the Gaussians, Ψ
    /// initialised from the run's `seed`. The evolution state is sized by
    /// [`PerGaussianState::prepare`] (or replaced by [`PerGaussianState::load_state`]).
    pub fn new(
        settings: &ScgsSettings,
        evogs: &EvoSettings,
        half_extent: f32,
        seed: u64,
    ) -> Result<Self, BackboneError> {
        let evogs = evogs.clone();
        evogs.validate()?;
        let columns = evolved_columns(evogs.evo.layout)?;
        let evo = unsized_state(evogs.evo, seed)?;
        Ok(Self {
            settings: *settings,
            evogs,
            seed,
            params: ScgsParams::new(settings, half_extent, seed)?,
            columns,
            evo,
            ready: false,
            training: None,
            backward: None,
            arap_loss: 0.0,
            neighbours: knn::NeighbourCache::default(),
        })
    }

    /// The evolution state (one row per control point).
    pub fn evo(&self) -> &EvoState {
        &self.evo
    }

    /// The control points' canonical positions.
    pub fn control_positions(&self) -> &[[f32; 3]] {
        &self.params.positions
    }

    /// The observation `z` at `time`: the evolved columns of the network's outputs at every
    /// control point (M × D, in the evolution layout's order).
    pub fn observations_at(&self, time: f32) -> Result<Vec<f32>, BackboneError> {
        let nodes = self
            .params
            .node_outputs(time, &mut DeformCache::default())?;
        Ok(gather(&nodes, NODE_OUTPUT, &self.columns))
    }

    fn control_count(&self) -> usize {
        self.params.positions.len()
    }

    fn check_ready(&self) -> Result<(), BackboneError> {
        if !self.ready {
            return Err(BackboneError::config(
                "evolution state",
                "not initialised: train the run, or load its evo_state.safetensors",
            ));
        }
        let m = self.control_count();
        if self.evo.rows() != m {
            return Err(BackboneError::config(
                "evolution state",
                format!(
                    "holds {} rows but the run has {m} control points",
                    self.evo.rows()
                ),
            ));
        }
        Ok(())
    }

    /// evo-state's forward at `time` with observations `z`; with re-queried history the network
    /// is asked at the history times, and `keep` keeps those queries' caches.
    fn evolve(
        &self,
        time: f32,
        z: &[f32],
        step: &mut Step,
        keep: bool,
    ) -> Result<Vec<(f32, DeformCache)>, BackboneError> {
        let mut caches = Vec::new();
        let result = match self.evogs.evo.history {
            HistoryMode::Buffer => self.evo.forward_into(time, z, None, step),
            HistoryMode::Requery => {
                let mut source =
                    |t: f32,
                     out: &mut [f32]|
                     -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
                        let mut cache = DeformCache::default();
                        let nodes = self.params.node_outputs(t, &mut cache)?;
                        out.copy_from_slice(&gather(&nodes, NODE_OUTPUT, &self.columns));
                        if keep {
                            caches.push((t, cache));
                        }
                        Ok(())
                    };
                self.evo.forward_into(time, z, Some(&mut source), step)
            }
        };
        result?;
        Ok(caches)
    }

    /// A fresh evolution state for the same frames and extent (Ψ kept): nothing committed yet.
    fn restart_state(&mut self) -> Result<(), BackboneError> {
        if !self.ready {
            return Ok(());
        }
        let frames = self.evo.frames().clone();
        let evo = empty_state(*self.evo.config(), frames, self.control_count(), &self.evo)?;
        self.evo = evo;
        self.training = None;
        Ok(())
    }
}

impl Parameters for ScgsControlEvo {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        let mut out: Vec<(String, StoreRef<'_>)> = self
            .params
            .named_params()
            .into_iter()
            .map(|(n, s)| (format!("{PHI}{n}"), s))
            .collect();
        out.push((PSI.to_string(), self.evo.psi().mlp().params()));
        out
    }

    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        let Self { params, evo, .. } = self;
        let mut out: Vec<(String, StoreMut<'_>)> = params
            .named_params_mut()
            .into_iter()
            .map(|(n, s)| (format!("{PHI}{n}"), s))
            .collect();
        out.push((PSI.to_string(), evo.psi_mut().mlp_mut().params_mut()));
        out
    }
}

impl Backbone for ScgsControlEvo {
    fn name(&self) -> &'static str {
        "evogs"
    }

    fn initialise(&mut self, canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        self.params.place(canonical.means, self.seed);
        self.restart_state()
    }

    fn gaussians_changed(&mut self, canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        if !self.settings.follow_densify {
            return Ok(());
        }
        // The trajectories are the network's, before the evolution's correction.
        let parents = self.params.follow(
            canonical.means,
            self.seed,
            self.settings.placement,
            self.settings.neighbours,
        )?;
        if self.ready && !parents.is_empty() {
            self.evo.apply_rows(&RowPlan {
                kept: Vec::new(),
                parent_from_new: parents,
            })?;
        }
        self.training = None;
        Ok(())
    }

    fn control_points_at(&mut self, time: f32) -> Result<Option<Vec<[f32; 3]>>, BackboneError> {
        self.check_ready()?;
        let nodes = self
            .params
            .node_outputs(time, &mut DeformCache::default())?;
        let z = gather(&nodes, NODE_OUTPUT, &self.columns);
        let mut step = Step::empty();
        self.evolve(time, &z, &mut step, false)?;
        let mut blended = nodes;
        scatter(&mut blended, NODE_OUTPUT, &self.columns, step.corrected());
        Ok(Some(moved(&self.params.positions, &blended)))
    }

    fn forward_into(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), BackboneError> {
        self.check_ready()?;
        let mut kept = self.training.take();
        let mut net = kept
            .as_mut()
            .map(|t| std::mem::take(&mut t.net))
            .unwrap_or_default();
        let nodes = self.params.node_outputs(time, &mut net)?;
        let z = gather(&nodes, NODE_OUTPUT, &self.columns);
        let mut step = kept.map_or_else(Step::empty, |t| t.step);
        let history = self.evolve(time, &z, &mut step, training)?;
        let mut blended = nodes.clone();
        scatter(&mut blended, NODE_OUTPUT, &self.columns, step.corrected());
        let neighbours = self.params.skin(
            &mut self.neighbours,
            self.settings.neighbours,
            canonical.means,
            &blended,
            out,
        )?;
        if training {
            self.training = Some(Training {
                time,
                means: canonical.means.to_vec(),
                neighbours,
                nodes,
                blended,
                net,
                z,
                step,
                history,
                rows: out.clone(),
                committed: false,
            });
        }
        Ok(())
    }

    fn backward_into(
        &mut self,
        d_deform: &[f32],
        out: &mut Vec<Vec<f32>>,
    ) -> Result<(), BackboneError> {
        let t = self.training.as_mut().ok_or_else(no_training_forward)?;
        if t.committed {
            return Err(BackboneError::config(
                "backbone",
                "backward called twice for one training forward",
            ));
        }
        let expected = t.means.len() * ROW;
        if d_deform.len() != expected {
            return Err(BackboneError::config(
                "scgs",
                format!("{} row gradients for {expected} values", d_deform.len()),
            ));
        }
        let m = self.params.positions.len();
        let skin = skinning::skin_backward(
            &t.means,
            &t.neighbours,
            self.params.controls(),
            &t.blended,
            d_deform,
        );
        let d_corrected = gather(&skin.nodes, NODE_OUTPUT, &self.columns);
        let mut bw = self.backward.take().unwrap_or_default();
        self.evo
            .backward_into(&t.step, &t.z, &d_corrected, &vec![1.0; m], &mut bw)?;
        // (`t` holds `self.training`: the setting is read field by field.)
        let want = self.settings.position_lr_scale > 0.0;
        // The evolved columns' gradient becomes the evolution's dL/dz; the others pass through.
        let mut skin = skin;
        scatter(&mut skin.nodes, NODE_OUTPUT, &self.columns, &bw.dz);
        // ARAP's gradient at the step's time rides the same backward pass.
        let arap = self.params.arap_terms(
            self.settings.arap_weight,
            arap_partner(self.seed, t.time),
            &t.nodes,
        )?;
        if let Some(terms) = &arap {
            terms.add_to_nodes(&mut skin.nodes);
        }
        let mut grads = self.params.node_gradients(&t.net, skin, want)?;
        // Re-queried history: the prior is a function of the network at the history times.
        for hg in &bw.history {
            let (_, cache) = t
                .history
                .iter()
                .find(|(time, _)| *time == hg.time)
                .ok_or_else(|| {
                    BackboneError::config(
                        "backbone",
                        format!("no cache of the network at the history time {}", hg.time),
                    )
                })?;
            let mut d = vec![0f32; m * NODE_OUTPUT];
            scatter(&mut d, NODE_OUTPUT, &self.columns, &hg.dz);
            let g = self.params.net.backward(cache, &d, want)?;
            add_into(&mut grads[0], &g.mlp);
            if let Some(p) = &g.positions {
                add_into(&mut grads[1], p);
            }
        }
        self.arap_loss = self.params.finish_arap(arap, want, &mut grads)?;
        let psi_len = self.evo.psi().param_count();
        grads.push(bw.dpsi.clone().unwrap_or_else(|| vec![0.0f32; psi_len]));
        *out = grads;
        self.evo.commit(&t.step)?;
        t.committed = true;
        self.backward = Some(bw);
        Ok(())
    }

    fn params(&self) -> Vec<(String, StoreRef<'_>)> {
        self.named_params()
    }

    fn params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        self.named_params_mut()
    }

    fn lr_scale(&self, name: &str) -> f32 {
        name.strip_prefix(PHI)
            .map_or(1.0, |n| super::position_lr_scale(n, &self.settings))
    }

    fn own_schedule(&self, name: &str) -> Option<LrSchedule> {
        (name == PSI)
            .then_some(self.evogs.psi_lr)
            .flatten()
            .map(LrSchedule::Constant)
    }

    fn loss_terms(&self) -> f64 {
        self.backward.as_ref().map_or(0.0, |b| {
            self.evogs.evo.lambda_sup as f64 * b.losses.sup
                + self.evogs.evo.lambda_prior as f64 * b.losses.prior
        }) + self.arap_loss
    }

    fn layout(&self) -> Layout {
        Layout::GEOMETRY
    }

    fn state(&self) -> Option<&dyn PerGaussianState> {
        Some(self)
    }

    fn state_mut(&mut self) -> Option<&mut dyn PerGaussianState> {
        Some(self)
    }

    fn save(&self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::save(path, self)?)
    }

    fn load(&mut self, path: &Path) -> Result<(), BackboneError> {
        Ok(tiny_nn::weights::load(path, self)?)
    }
}

/// The state belongs to the control points: [`PerGaussianState::rows`] counts them, and
/// densification finds no per-Gaussian arrays in it.
impl PerGaussianState for ScgsControlEvo {
    fn prepare(
        &mut self,
        frame_times: &[f32],
        _rows: usize,
        extent: f32,
    ) -> Result<(), BackboneError> {
        if self.ready {
            return self.check_ready();
        }
        let m = self.control_count();
        let evo = sized_state(self.evogs.evo, frame_times, m, extent, &self.evo)?;
        self.evo = evo;
        self.ready = true;
        Ok(())
    }

    fn rows_mut(&mut self) -> Vec<&mut dyn PerGaussian> {
        // The Gaussians' rows change under the kept step.
        self.training = None;
        Vec::new()
    }

    fn rows(&self) -> usize {
        self.evo.rows()
    }

    fn state_bytes(&self) -> usize {
        self.evo.state_bytes()
    }

    fn densify_cues(&self, _extent: f32) -> Result<DensifyCues, BackboneError> {
        Ok(DensifyCues::default())
    }

    fn motion_stats(&self) -> Option<&[evo_state::Stats]> {
        None
    }

    fn latest_step(&self) -> Option<&Step> {
        None
    }

    fn latest_deformation(&self) -> Option<Deformation<'_>> {
        self.training.as_ref().map(|t| Deformation {
            corrected: &t.rows,
            layout: Layout::GEOMETRY,
        })
    }

    fn gain_stats(&self) -> Option<GainStats> {
        let t = self.training.as_ref()?;
        GainStats::of(t.step.gains(), t.step.rows())
    }

    fn save_state(&self, path: &Path) -> Result<(), BackboneError> {
        save_state_file(&self.evo, path)
    }

    fn load_state(&mut self, path: &Path) -> Result<(), BackboneError> {
        let evo = load_state_file(path, &self.evogs.evo, &self.evo)?;
        if evo.rows() != self.control_count() {
            return Err(BackboneError::file(
                path,
                format!(
                    "field `rows`: {} rows, the run has {} control points",
                    evo.rows(),
                    self.control_count()
                ),
            ));
        }
        self.evo = evo;
        self.ready = true;
        self.training = None;
        Ok(())
    }
}
