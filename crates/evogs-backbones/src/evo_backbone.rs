//! The EvoGS backbone (DESIGN §4–5): the observation network Φ wrapped by evo-state's
//! [`EvoState`] with its gain network Ψ. Φ is any [`Observer`]: EvoGS(D-3DGS)'s tri-plane +
//! cubic B-spline + MLP at half the baseline's width ([`ObservationNet`], the default),
//! EvoGS(4DGS)'s HexPlane field ([`crate::hex_phi::HexPhi`]) or EvoGS(Grid4D)'s hash-grid field
//! ([`crate::grid4d_phi::Grid4dPhi`]), each at half its width.
//!
//! - Training forward (`training = true`): z = Φ(canonical means, t), then evo-state's forward at
//!   t; the corrected d̃ is the deformation. The step, z, Φ's cache and the stop-gradient
//!   opacities are kept for the backward.
//! - Backward: evo-state's backward gives dL/dz (L_render + λ1 L_sup + λ2 L_prior) and dL/dΨ;
//!   Φ's backward turns dL/dz into parameter gradients. With history re-queried from Φ ("without
//!   buffer") the prior d̂ is a function of Φ at the history times: the training forward keeps
//!   those queries' caches and the backward adds Φ's gradients through them (DESIGN §4.11). The step
//!   is then committed (its frame's buffer and memory blocks, valid flag, Ψ's input RMS): "commit
//!   after the step".
//! - Evaluation forward (`training = false`): the same read-only query at any time, nothing kept,
//!   nothing written.
//!
//! Parameter buffers: Φ's (`phi.*`), then Ψ's (`psi`), each its own Adam group (Ψ at its own
//! constant lr, [`EvoSettings::psi_lr`], or the network schedule for older runs). The evolution
//! state is the backbone's [`PerGaussianState`]: a per-Gaussian container for densification
//! ([`PerGaussianState::rows_mut`]), saved and loaded whole with evo-state's safetensors format
//! ([`PerGaussianState::save_state`]).
//!
//! The deformation rows are the evolution state's own: its [`Layout`] holds
//! any subset of the components (D <= 14, only enabled ones cost anything) and
//! [`Backbone::layout`] tells the trainer which, so the corrected d̃ is handed over as it is and
//! the gradient comes back in the same columns (no rearranging either way).

use std::path::Path;

use densify::{Deformation, PerGaussian, Planned};
use evo_state::{Backward, EvoConfig, EvoError, EvoState, Frames, Step};
use rayon::prelude::*;
use splat_core::{GaussiansView, Layout, sigmoid};
use tiny_nn::{
    BSplineConfig, LrSchedule, ObservationConfig, ObservationNet, Parameters, StoreMut, StoreRef,
    TriPlaneConfig,
};

use crate::backbone::{
    Backbone, DensifyCues, GainStats, PerGaussianState, fill_inputs, no_training_forward,
};
use crate::error::BackboneError;
use crate::evo_settings::EvoSettings;
use crate::observer::Observer;

/// Φ's configuration for a run: half the baseline network's width (`net_width`), scene box
/// `[-h, h]³` of the initial cube (`half_extent`), output D, initialised from the run's `seed`.
pub fn observation_config(
    settings: &EvoSettings,
    net_width: usize,
    half_extent: f32,
    seed: u64,
) -> ObservationConfig {
    let s = settings;
    let h = half_extent;
    let mut triplane = TriPlaneConfig::new(
        s.triplane_channels,
        &s.triplane_resolutions,
        s.triplane_combine,
    );
    triplane.box_min = [-h; 3];
    triplane.box_max = [h; 3];
    ObservationConfig {
        triplane,
        bspline: BSplineConfig::new(s.bspline_controls, s.bspline_width),
        width: (net_width / 2).max(1),
        hidden_layers: s.hidden_layers,
        output: s.evo.dim(),
        precision: s.net_precision,
        seed: seed ^ 0xE70_6500,
    }
}

/// The evolution state of `config` before a run sizes it (no frames, no rows), Ψ initialised from
/// the run's `seed`: what an EvoGS backbone is built with.
pub(crate) fn unsized_state(config: EvoConfig, seed: u64) -> Result<EvoState, BackboneError> {
    let placeholder = Frames::from_timestamps([0.0])
        .map_err(|e| BackboneError::config("frames", e.to_string()))?;
    Ok(EvoState::new(config, placeholder, 0, seed ^ 0x9A1_0000)?)
}

/// A state of `config` at the scene's `extent` for the training `frame_times` and `rows` rows,
/// nothing committed, Ψ that of `like` ([`PerGaussianState::prepare`]).
pub(crate) fn sized_state(
    config: EvoConfig,
    frame_times: &[f32],
    rows: usize,
    extent: f32,
    like: &EvoState,
) -> Result<EvoState, BackboneError> {
    let frames = Frames::from_timestamps(frame_times.iter().copied())
        .map_err(|e| BackboneError::config("frames", e.to_string()))?;
    empty_state(EvoConfig { extent, ..config }, frames, rows, like)
}

/// A state of `config` over `frames` with `rows` rows and nothing committed, Ψ that of `like`.
pub(crate) fn empty_state(
    config: EvoConfig,
    frames: Frames,
    rows: usize,
    like: &EvoState,
) -> Result<EvoState, BackboneError> {
    let mut evo = EvoState::new(config, frames, rows, 0)?;
    evo.psi_mut().set_params(&like.psi().params())?;
    Ok(evo)
}

/// Writes `evo` to `path` ([`PerGaussianState::save_state`]); an error names the file once.
pub(crate) fn save_state_file(evo: &EvoState, path: &Path) -> Result<(), BackboneError> {
    evo.save(path).map_err(|e| match e {
        EvoError::Io { path, source } => BackboneError::file(path, source.to_string()),
        e => BackboneError::file(path, e.to_string()),
    })
}

/// Reads the state at `path` of a run whose evolution settings are `config` (the extent is the
/// scene's, saved with the state) and whose Ψ has the shape of `like`'s
/// ([`PerGaussianState::load_state`]); a mismatch names the file and the field.
pub(crate) fn load_state_file(
    path: &Path,
    config: &EvoConfig,
    like: &EvoState,
) -> Result<EvoState, BackboneError> {
    if !path.is_file() {
        return Err(BackboneError::file(
            path,
            "missing: an evogs run keeps its evolution state here",
        ));
    }
    let evo = EvoState::load(path).map_err(|e| BackboneError::file(path, e.to_string()))?;
    let want = EvoConfig {
        extent: evo.config().extent,
        ..*config
    };
    if *evo.config() != want {
        return Err(BackboneError::file(
            path,
            format!(
                "field `config`: evolution settings {:?} differ from the run's {:?}",
                evo.config(),
                want
            ),
        ));
    }
    if evo.psi().param_count() != like.psi().param_count() {
        return Err(BackboneError::file(
            path,
            "field `psi`: Ψ has another shape",
        ));
    }
    Ok(evo)
}

/// What the last training forward kept for its backward.
struct Training<C> {
    step: Step,
    z: Vec<f32>,
    cache: C,
    /// Φ's caches at the re-queried history times (history `requery` only).
    history_caches: Vec<(f32, C)>,
    opacity: Vec<f32>,
    committed: bool,
}

/// Φ with the evolution state and Ψ.
pub struct EvoBackbone<P: Observer = ObservationNet> {
    settings: EvoSettings,
    phi: P,
    /// The evolution state, kept as one of densification's per-Gaussian arrays.
    evo: Planned<EvoState>,
    /// Whether `evo` was built for the run's frames and Gaussians (or loaded).
    ready: bool,
    training: Option<Training<P::Cache>>,
    backward: Option<Backward>,
    /// Φ's own regulariser of the last backward (weighted).
    phi_regulariser: f64,
    positions: Vec<f32>,
    times: Vec<f32>,
}

impl EvoBackbone<ObservationNet> {
    /// EvoGS(D-3DGS): the tri-plane Φ and Ψ for a run (its EvoGS settings, the baseline
    /// network's width, the half extent of its initial cube), initialised from its seed
    /// ([`observation_config`]). The evolution state is sized by [`PerGaussianState::prepare`]
    /// (or replaced by [`PerGaussianState::load_state`]).
    pub fn new(
        settings: &EvoSettings,
        net_width: usize,
        half_extent: f32,
        seed: u64,
    ) -> Result<Self, BackboneError> {
        let phi = ObservationNet::new(observation_config(settings, net_width, half_extent, seed))?;
        Self::with_phi(settings, seed, phi)
    }
}

impl<P: Observer> EvoBackbone<P> {
    /// Φ (built for `settings`' components) with Ψ for a run, Ψ initialised from its `seed`.
    pub fn with_phi(settings: &EvoSettings, seed: u64, phi: P) -> Result<Self, BackboneError> {
        let settings = settings.clone();
        settings.validate()?;
        let layout = settings.evo.layout;
        if phi.output_width() != layout.dim() {
            return Err(BackboneError::config(
                "evogs.components",
                format!(
                    "Φ gives {} values per Gaussian, the components `{}` need {}",
                    phi.output_width(),
                    layout,
                    layout.dim()
                ),
            ));
        }
        // The extent is the scene's: `prepare` builds the state again with it.
        let evo = Planned(unsized_state(settings.evo, seed)?);
        Ok(Self {
            settings,
            phi,
            evo,
            ready: false,
            training: None,
            backward: None,
            phi_regulariser: 0.0,
            positions: Vec::new(),
            times: Vec::new(),
        })
    }

    /// The evolution state.
    pub fn evo(&self) -> &EvoState {
        &self.evo
    }

    /// The observation network Φ.
    pub fn phi(&self) -> &P {
        &self.phi
    }

    /// The settings.
    pub fn settings(&self) -> &EvoSettings {
        &self.settings
    }

    /// The EvoGS loss terms of the last backward (unweighted `L_sup`, `L_prior`).
    pub fn last_losses(&self) -> Option<evo_state::Losses> {
        self.backward.as_ref().map(|b| b.losses)
    }

    fn check_ready(&self, rows: usize) -> Result<(), BackboneError> {
        if !self.ready {
            return Err(BackboneError::config(
                "evolution state",
                "not initialised: train the run, or load its evo_state.safetensors",
            ));
        }
        if self.evo.rows() != rows {
            return Err(BackboneError::config(
                "evolution state",
                format!(
                    "holds {} Gaussians but the scene has {rows} (not aligned)",
                    self.evo.rows()
                ),
            ));
        }
        Ok(())
    }

    /// evo-state's forward at `time` with observations `z`. With re-queried history, Φ is
    /// queried at the history times; `keep` keeps those queries' caches (for a training step's
    /// backward) in the returned list.
    fn evolve(
        &self,
        time: f32,
        z: &[f32],
        step: &mut Step,
        keep: bool,
    ) -> Result<Vec<(f32, P::Cache)>, BackboneError> {
        let mut caches = Vec::new();
        let result = match self.settings.evo.history {
            evo_state::HistoryMode::Buffer => self.evo.forward_into(time, z, None, step),
            evo_state::HistoryMode::Requery => {
                let (phi, positions) = (&self.phi, &self.positions);
                let n = positions.len() / 3;
                let mut source =
                    |t: f32,
                     out: &mut [f32]|
                     -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
                        let (zt, cache) = phi.observe(positions, &vec![t; n], n)?;
                        out.copy_from_slice(&zt);
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
}

impl<P: Observer> Parameters for EvoBackbone<P> {
    fn named_params(&self) -> Vec<(String, StoreRef<'_>)> {
        let mut out: Vec<(String, StoreRef<'_>)> = self
            .phi
            .named_params()
            .into_iter()
            .map(|(n, s)| (format!("phi.{n}"), s))
            .collect();
        out.push(("psi".to_string(), self.evo.psi().mlp().params()));
        out
    }

    fn named_params_mut(&mut self) -> Vec<(String, StoreMut<'_>)> {
        let Self { phi, evo, .. } = self;
        let mut out: Vec<(String, StoreMut<'_>)> = phi
            .named_params_mut()
            .into_iter()
            .map(|(n, s)| (format!("phi.{n}"), s))
            .collect();
        out.push(("psi".to_string(), evo.psi_mut().mlp_mut().params_mut()));
        out
    }
}

impl<P: Observer> Backbone for EvoBackbone<P> {
    fn name(&self) -> &'static str {
        "evogs"
    }

    fn initialise(&mut self, canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        self.phi.initialise(canonical.means)
    }

    fn control_points_at(&mut self, time: f32) -> Result<Option<Vec<[f32; 3]>>, BackboneError> {
        self.phi.control_points_at(time)
    }

    fn gaussians_changed(&mut self, canonical: GaussiansView<'_>) -> Result<(), BackboneError> {
        self.phi.gaussians_changed(canonical.means)
    }

    fn forward_into(
        &mut self,
        canonical: GaussiansView<'_>,
        time: f32,
        training: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), BackboneError> {
        let n = canonical.len();
        self.check_ready(n)?;
        fill_inputs(canonical, time, &mut self.positions, &mut self.times);
        let mut kept = self.training.take();
        let mut cache = kept
            .as_mut()
            .map(|t| std::mem::take(&mut t.cache))
            .unwrap_or_default();
        let z = self
            .phi
            .observe_into(&self.positions, &self.times, n, &mut cache)?;
        let (mut step, mut opacity) =
            kept.map_or_else(|| (Step::empty(), Vec::new()), |t| (t.step, t.opacity));
        let history_caches = self.evolve(time, &z, &mut step, training)?;
        out.clear();
        out.extend_from_slice(step.corrected());
        if training {
            opacity.clear();
            opacity.par_extend(canonical.opacity_logits.par_iter().map(|&o| sigmoid(o)));
            self.training = Some(Training {
                step,
                z,
                cache,
                history_caches,
                opacity,
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
        let layout = self.settings.evo.layout;
        let n = t.step.rows();
        if d_deform.len() != n * layout.dim() {
            return Err(BackboneError::config(
                "backbone",
                format!(
                    "deformation gradient has {} values, expected {n} × {} (`{layout}`)",
                    d_deform.len(),
                    layout.dim()
                ),
            ));
        }
        let mut bw = self.backward.take().unwrap_or_default();
        self.evo
            .backward_into(&t.step, &t.z, d_deform, &t.opacity, &mut bw)?;
        let mut grads = self.phi.gradients(&t.cache, &bw.dz)?;
        // Re-queried history: d̂ = z(t_k1) + s (z(t_k1) - z(t_k2)) reaches Φ at those times.
        for hg in &bw.history {
            let (_, cache) = t
                .history_caches
                .iter()
                .find(|(time, _)| *time == hg.time)
                .ok_or_else(|| {
                    BackboneError::config(
                        "backbone",
                        format!("no cache of Φ at the history time {}", hg.time),
                    )
                })?;
            let gh = self.phi.gradients(cache, &hg.dz)?;
            for (g, h) in grads.iter_mut().zip(gh) {
                g.iter_mut().zip(h).for_each(|(a, b)| *a += b);
            }
        }
        self.phi_regulariser = self.phi.regularise(&t.cache, &mut grads)?;
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

    fn loss_terms(&self) -> f64 {
        self.backward.as_ref().map_or(0.0, |b| {
            self.settings.evo.lambda_sup as f64 * b.losses.sup
                + self.settings.evo.lambda_prior as f64 * b.losses.prior
                + self.phi_regulariser
        })
    }

    fn own_schedule(&self, name: &str) -> Option<LrSchedule> {
        match name.strip_prefix("phi.") {
            Some(phi) => self.phi.own_schedule(phi),
            None => (name == "psi")
                .then_some(self.settings.psi_lr)
                .flatten()
                .map(LrSchedule::Constant),
        }
    }

    fn lr_scale(&self, name: &str) -> f32 {
        name.strip_prefix("phi.").map_or(1.0, |phi| {
            self.phi.lr_scale(phi, self.settings.grid_lr_scale)
        })
    }

    fn layout(&self) -> Layout {
        self.settings.evo.layout
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

impl<P: Observer> PerGaussianState for EvoBackbone<P> {
    fn prepare(
        &mut self,
        frame_times: &[f32],
        rows: usize,
        extent: f32,
    ) -> Result<(), BackboneError> {
        if self.ready {
            return self.check_ready(rows);
        }
        let evo = sized_state(self.settings.evo, frame_times, rows, extent, &self.evo)?;
        self.evo = Planned(evo);
        self.ready = true;
        Ok(())
    }

    fn rows_mut(&mut self) -> Vec<&mut dyn PerGaussian> {
        // The kept step becomes stale once rows change.
        self.training = None;
        vec![&mut self.evo]
    }

    fn rows(&self) -> usize {
        self.evo.rows()
    }

    fn state_bytes(&self) -> usize {
        self.evo.state_bytes()
    }

    fn densify_cues(&self, extent: f32) -> Result<DensifyCues, BackboneError> {
        let Some(t) = &self.training else {
            return Ok(DensifyCues::default());
        };
        let layout = self.settings.evo.layout;
        Ok(DensifyCues {
            residual_norm: t.step.residual_norms(&t.z, layout, extent)?,
            theta: t.step.thetas(),
        })
    }

    fn motion_stats(&self) -> Option<&[evo_state::Stats]> {
        self.training.as_ref().and_then(|t| t.step.stats())
    }

    fn latest_step(&self) -> Option<&evo_state::Step> {
        self.training.as_ref().map(|t| &t.step)
    }

    fn latest_deformation(&self) -> Option<Deformation<'_>> {
        self.training.as_ref().map(|t| Deformation {
            corrected: t.step.corrected(),
            layout: self.settings.evo.layout,
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
        let evo = load_state_file(path, &self.settings.evo, &self.evo)?;
        self.evo = Planned(evo);
        self.ready = true;
        self.training = None;
        Ok(())
    }
}
