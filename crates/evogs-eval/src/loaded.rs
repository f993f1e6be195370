//! A trained run read back ([`LoadedRun`]): from its end-of-run files, or from the checkpoint of a
//! run that is still training, with the rasterizer that evaluation and rendering use.

use std::path::Path;

use evogs_backbones::Backbone;
use evogs_train::TrainError;
use evogs_train::run::{
    RunFile, RunPaths, TrainSummary, read_checkpoint, read_json, read_run_file,
};
use evogs_train::timers::PhaseTimes;
use evogs_train::trainer::{deformed_gaussians, make_backbone};
use splat_raster::{
    BackendChoice, BackendInfo, CpuRasterizer, DynRasterizer, Gaussians, select_rasterizer,
};

/// A trained run read back for evaluation, rendering and export.
pub struct LoadedRun {
    /// Its paths.
    pub paths: RunPaths,
    /// `config.json`.
    pub run: RunFile,
    /// `train_metrics.json`.
    pub summary: TrainSummary,
    /// Canonical Gaussians (`canonical.ply`).
    pub canonical: Gaussians,
    /// Backbone with the run's weights.
    pub backbone: Box<dyn Backbone>,
    /// The rasterizer evaluation and rendering use: the CPU one unless
    /// [`LoadedRun::use_backend`] chose another.
    pub raster: DynRasterizer,
}

impl LoadedRun {
    /// The run's dataset directory, or an error naming `config.json`'s `data` when it is no
    /// longer there ([`evogs_train::run::run_data`]).
    pub fn data(&self) -> Result<&Path, TrainError> {
        evogs_train::run::run_data(&self.paths, &self.run)
    }

    /// Opens a run directory written by [`evogs_train::train`].
    pub fn open(root: &Path) -> Result<Self, TrainError> {
        let (paths, run) = read_run_file(root)?;
        let summary: TrainSummary = read_json(&paths.train_metrics())?;
        let canonical = evogs_io::read_ply(&paths.canonical())?.gaussians;
        let mut backbone = make_backbone(&run.train)?;
        backbone.load(&paths.weights())?;
        backbone.load_state(&paths.evo_state())?;
        Ok(Self {
            paths,
            run,
            summary,
            canonical,
            backbone,
            raster: Box::new(CpuRasterizer::new()),
        })
    }

    /// Opens a run that is still training from its checkpoint (`checkpoint.safetensors`, read
    /// by the trainer's loader) instead of the end-of-run files: the Gaussians and backbone of
    /// the last checkpoint, with (EvoGS) the evolution state written with it, which is still
    /// `evo_state.<iteration>.safetensors` for a moment after the checkpoint lands. Reads only:
    /// nothing in the run directory changes. The summary holds the checkpoint's iteration, the
    /// planned iterations and Gaussians; what only the end of the run knows (time, last loss
    /// and PSNR) is NaN or zero.
    pub fn open_checkpoint(root: &Path) -> Result<Self, TrainError> {
        let (paths, run) = read_run_file(root)?;
        let (state, mut backbone, meta) = read_checkpoint(&paths.checkpoint(), &run.train)?;
        let pending = paths.pending_evo_state(meta.iteration);
        let evo_state = if pending.is_file() {
            pending
        } else {
            paths.evo_state()
        };
        backbone.load_state(&evo_state)?;
        let canonical = state.gaussians().clone();
        let summary = TrainSummary {
            iteration: meta.iteration,
            iterations: run.train.iterations,
            iterations_this_process: 0,
            seconds: 0.0,
            iterations_per_second: 0.0,
            last_loss: f64::NAN,
            last_psnr: f64::NAN,
            gaussians: canonical.len(),
            net_width: run.train.net.width,
            phases: PhaseTimes::default(),
            gain: None,
            budget: run
                .train
                .budget
                .zip(meta.budget)
                .map(|(budget, p)| evogs_train::budget::BudgetSummary::new(budget, &p)),
            traffic_per_iteration: None,
            device_ms_per_iteration: None,
            network: String::new(),
            loss: String::new(),
        };
        Ok(Self {
            paths,
            run,
            summary,
            canonical,
            backbone,
            raster: Box::new(CpuRasterizer::new()),
        })
    }

    /// Renders with the backend `choice` from now on; says which it is.
    pub fn use_backend(&mut self, choice: BackendChoice) -> Result<BackendInfo, TrainError> {
        let (raster, info) = select_rasterizer(choice)?;
        self.raster = raster;
        Ok(info)
    }

    /// Whether the run got past its warm-up (the network is used only then).
    pub fn deforms(&self) -> bool {
        self.summary.schedule_iteration() >= self.run.train.warm_up
    }

    /// The deformed Gaussians at any finite `time` (a non-finite one is an error naming the
    /// field `time`).
    pub fn deformed(&mut self, time: f32) -> Result<Gaussians, TrainError> {
        if !time.is_finite() {
            return Err(TrainError::config(
                "time",
                format!("{time} is not a finite number"),
            ));
        }
        let deforms = self.deforms();
        deformed_gaussians(&self.canonical, self.backbone.as_mut(), deforms, time)
    }
}
