//! Run directories: what a training run writes and how it is read back.
//!
//! Layout of `RUN/`:
//! - `config.json`: the dataset directory and every setting ([`RunFile`]);
//! - `checkpoint.safetensors`: everything needed to continue ([`crate::checkpoint`]), rewritten
//!   every `checkpoint_every` iterations and at the end;
//! - `canonical.ply`: the canonical Gaussians in the 3DGS PLY layout;
//! - `deform.safetensors`: the backbone's weights (EvoGS: Φ as `phi.*` and Ψ as `psi`);
//! - `evo_state.safetensors` (EvoGS only): the evolution state (buffer, valid frames, memory, Ψ),
//!   evo-state's own format, written together with every checkpoint. The pair is committed so
//!   that a kill at any moment leaves a matching pair (`save_resumable`): the state is first
//!   written as `evo_state.<iteration>.safetensors`, then the checkpoint is renamed into place,
//!   then the state; a resume finishes or discards what a kill interrupted;
//! - `train_log.jsonl`: one line per `log_every` iterations (loss, PSNR, Gaussians, it/s, peak
//!   memory, K for EvoGS; [`crate::train_log`]);
//! - `train_metrics.json`: iterations done, time, iterations/s, last loss and PSNR, Gaussians,
//!   per-phase times ([`TrainSummary`]);
//! - `eval_<split>.json`, `eval_<split>.md`, `renders/<split>/*.png`: written by evaluation.
//!
//! Every file is written to a temporary file and renamed into place; the temporary files a kill
//! leaves behind are removed when the run starts or resumes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use evogs_io::Split;
use serde::{Deserialize, Serialize};

use evogs_backbones::Backbone;

use crate::budget::{BudgetProgress, BudgetSummary, Clock, Pacer, clock_of};
use crate::checkpoint::{CheckpointMeta, load_checkpoint, save_checkpoint};
use crate::config::TrainConfig;
use crate::data::{load_dataset_split, open_dataset};
use crate::error::TrainError;
pub use crate::run_files::{read_json, write_json, write_text};
use crate::state::SceneState;
use crate::timers::PhaseTimes;
use crate::train_log::TrainLog;
use crate::trainer::{StepReport, Trainer, make_backbone};

/// The paths of a run directory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunPaths {
    /// The directory.
    pub root: PathBuf,
}

impl RunPaths {
    /// Paths under `root`.
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }
    /// `config.json`.
    pub fn config(&self) -> PathBuf {
        self.root.join("config.json")
    }
    /// `checkpoint.safetensors`.
    pub fn checkpoint(&self) -> PathBuf {
        self.root.join("checkpoint.safetensors")
    }
    /// `canonical.ply`.
    pub fn canonical(&self) -> PathBuf {
        self.root.join("canonical.ply")
    }
    /// `deform.safetensors`.
    pub fn weights(&self) -> PathBuf {
        self.root.join("deform.safetensors")
    }
    /// `evo_state.safetensors` (EvoGS runs): the evolution state, written with every checkpoint.
    pub fn evo_state(&self) -> PathBuf {
        self.root.join("evo_state.safetensors")
    }
    /// `evo_state.<iteration>.safetensors`: the evolution state of the checkpoint at `iteration`
    /// while that checkpoint is being written (`save_resumable`); renamed to
    /// [`RunPaths::evo_state`] once the checkpoint is in place.
    pub fn pending_evo_state(&self, iteration: u64) -> PathBuf {
        self.root
            .join(format!("{PENDING_EVO_STATE_PREFIX}{iteration}.safetensors"))
    }
    /// `train_log.jsonl` ([`crate::train_log`]).
    pub fn train_log(&self) -> PathBuf {
        self.root.join("train_log.jsonl")
    }
    /// `train_metrics.json`.
    pub fn train_metrics(&self) -> PathBuf {
        self.root.join("train_metrics.json")
    }
    /// `eval_<split>.json`.
    pub fn eval_json(&self, split: Split) -> PathBuf {
        self.root.join(format!("eval_{split}.json"))
    }
    /// `eval_<split>.md`.
    pub fn eval_markdown(&self, split: Split) -> PathBuf {
        self.root.join(format!("eval_{split}.md"))
    }
    /// `renders/<split>/`.
    pub fn renders(&self, split: Split) -> PathBuf {
        self.root.join("renders").join(split.name())
    }

    /// Whether the directory holds a run: its `config.json` or its checkpoint.
    pub fn holds_run(&self) -> bool {
        self.config().is_file() || self.checkpoint().is_file()
    }

    /// Removes the run's own files, so that a new run in the directory cannot be mixed with
    /// an old one (`evogs train --force`): every file named here (configuration, checkpoint,
    /// PLY, weights, evolution state and its pending copies, log, metrics, the evaluations of
    /// every split), the renders, `evogs plot`'s `train_log.png` and the demo's `sweep/`.
    /// Anything else in the directory is left. Returns what it removed, in order.
    pub fn clear_run(&self) -> Result<Vec<PathBuf>, TrainError> {
        let mut removed = Vec::new();
        let entries = match std::fs::read_dir(&self.root) {
            Ok(entries) => entries,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(removed),
            Err(e) => return Err(TrainError::io(&self.root, e)),
        };
        let fixed = [
            self.config(),
            self.checkpoint(),
            self.canonical(),
            self.weights(),
            self.evo_state(),
            self.train_log(),
            self.train_metrics(),
            self.root.join("train_log.png"),
        ];
        let mut paths: Vec<PathBuf> = entries
            .map(|e| {
                e.map(|e| e.path())
                    .map_err(|e| TrainError::io(&self.root, e))
            })
            .collect::<Result<_, _>>()?;
        paths.sort();
        for path in paths {
            let name = path
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or_default();
            let own_dir = matches!(name, "renders" | "sweep") && path.is_dir();
            let own_file = path.is_file()
                && (fixed.contains(&path)
                    || (name.starts_with(PENDING_EVO_STATE_PREFIX)
                        && name.ends_with(".safetensors"))
                    || (name.starts_with("eval_")
                        && (name.ends_with(".json") || name.ends_with(".md"))));
            if own_dir {
                std::fs::remove_dir_all(&path).map_err(|e| TrainError::io(&path, e))?;
            } else if own_file {
                std::fs::remove_file(&path).map_err(|e| TrainError::io(&path, e))?;
            } else {
                continue;
            }
            removed.push(path);
        }
        Ok(removed)
    }
}

/// `config.json`: where the data is and how the run trains.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunFile {
    /// The D-NeRF dataset directory.
    pub data: PathBuf,
    /// The settings.
    pub train: TrainConfig,
}

/// `train_metrics.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainSummary {
    /// Iterations completed.
    pub iteration: u64,
    /// Iterations planned.
    pub iterations: u64,
    /// Iterations run by the last process (fewer than `iteration` after a resume).
    pub iterations_this_process: u64,
    /// Wall-clock seconds of the last process's loop.
    pub seconds: f64,
    /// `iterations_this_process / seconds`.
    pub iterations_per_second: f64,
    /// Loss of the last iteration.
    pub last_loss: f64,
    /// Training-view PSNR of the last iteration.
    pub last_psnr: f64,
    /// Gaussians at the end.
    pub gaussians: usize,
    /// Network width (results name the width they used).
    pub net_width: usize,
    /// Seconds per phase in the last process.
    pub phases: PhaseTimes,
    /// K's distribution over the gain-stage training steps of the last quarter of the run's
    /// schedule run by the last process (EvoGS with evolution on; `null` otherwise and in
    /// files written before it was recorded). DESIGN §4.9.
    #[serde(default)]
    pub gain: Option<crate::gain_report::GainSummary>,
    /// A budget run's budget, clock, budget spent and schedule iteration reached (absent
    /// without a budget).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub budget: Option<BudgetSummary>,
    /// Host–device traffic per iteration of the last process, the means over its iterations
    /// (in-training evaluations and densification included): the wgpu backend's counts
    /// ([`splat_raster::Traffic`]); absent on the CPU backend and in files written before it
    /// was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub traffic_per_iteration: Option<splat_raster::TrafficRate>,
    /// Where the last process ran the deformation network and why
    /// ([`crate::trainer::Placement`]'s line); empty in files written before it was
    /// recorded.
    #[serde(default)]
    pub network: String,
    /// The device's own time per iteration of the last process, milliseconds per labelled span
    /// of work (`raster forward`, `loss`, `raster backward`; GPU timestamps, means over its
    /// iterations, evaluations and densification included: [`Trainer::device_times`]); absent
    /// on the CPU backend, on an adapter without timestamps and in files written before it was
    /// recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device_ms_per_iteration: Option<std::collections::BTreeMap<String, f64>>,
    /// Where the last process ran the loss and why ([`crate::trainer::Placement`]'s line);
    /// empty in files written before it was recorded.
    #[serde(default)]
    pub loss: String,
}

impl TrainSummary {
    /// The schedule iteration reached: [`TrainSummary::iteration`] without a budget.
    pub fn schedule_iteration(&self) -> u64 {
        self.budget
            .as_ref()
            .map_or(self.iteration, |b| b.schedule_iteration)
    }
}

/// What `train` is asked to do.
#[derive(Clone, Debug)]
pub struct TrainRequest {
    /// Dataset directory (ignored when resuming: the run's `config.json` names it).
    pub data: PathBuf,
    /// Run directory.
    pub out: PathBuf,
    /// Settings (ignored when resuming).
    pub config: TrainConfig,
    /// Continue the run in `out` from its checkpoint.
    pub resume: bool,
    /// Stop after this many iterations in total even if the run plans more (an interruption;
    /// outputs and checkpoint are written as usual).
    pub stop_after: Option<u64>,
    /// When resuming: the rasterizer backend to continue on instead of the one the run recorded
    /// (then recorded in `config.json`). `None` keeps the run's. New runs use `config.backend`.
    pub resume_backend: Option<splat_raster::BackendChoice>,
    /// When resuming: where the deformation network continues instead of where the run
    /// recorded ([`TrainConfig::net_backend`], then recorded in `config.json`). `None` keeps
    /// the run's.
    pub resume_net_backend: Option<splat_raster::BackendChoice>,
}

impl TrainRequest {
    /// The iteration the run stops at at the latest: the last one `config` plans, or
    /// [`TrainRequest::stop_after`] if earlier; with a time budget, `stop_after` or none
    /// (`u64::MAX`: the budget decides). `config` is the run's own (on resume, the one its
    /// `config.json` records).
    pub fn end(&self, config: &TrainConfig) -> u64 {
        let planned = if config.budget.is_some() {
            u64::MAX
        } else {
            config.iterations
        };
        self.stop_after.map_or(planned, |s| s.min(planned))
    }
}

/// Whether [`train`] writes the resumable checkpoint right after the step `report` (after its
/// progress callback): every `checkpoint_every` iterations, and after the run's last step.
pub fn checkpoint_follows(config: &TrainConfig, report: &StepReport) -> bool {
    report.iteration.is_multiple_of(config.checkpoint_every) || report.last
}

/// File-name prefix of [`RunPaths::pending_evo_state`].
const PENDING_EVO_STATE_PREFIX: &str = "evo_state.";

/// Writes the checkpoint and (EvoGS) the evolution state of `trainer` as one resumable pair:
/// the state goes to [`RunPaths::pending_evo_state`] first, then the checkpoint replaces the
/// previous one, then the state replaces the previous state. A kill before the checkpoint's
/// rename leaves the previous pair (and a pending file [`settle_evo_state`] removes); a kill
/// after it leaves the new checkpoint with its state still pending (which
/// [`settle_evo_state`] renames). Either way the resumed run continues bit for bit.
fn save_resumable(
    paths: &RunPaths,
    trainer: &mut Trainer,
    budget: Option<BudgetProgress>,
    log: &TrainLog,
) -> Result<(), TrainError> {
    // What lives on a device (the network's parameters and moments) is written as the host's.
    trainer.sync_host()?;
    let pending = paths.pending_evo_state(trainer.iteration());
    let has_state = trainer.backbone().save_state(&pending)?;
    save_checkpoint(
        &paths.checkpoint(),
        trainer.state(),
        trainer.backbone(),
        trainer.iteration(),
        trainer.config().seed,
        budget,
        Some(log.interval()),
    )?;
    if has_state {
        std::fs::rename(&pending, paths.evo_state()).map_err(|e| TrainError::io(&pending, e))?;
    }
    Ok(())
}

/// Before a resume from the checkpoint at `iteration`: commits that checkpoint's evolution state
/// if a kill left it pending, and removes pending states of checkpoints that never landed and
/// the temporary files of interrupted writes.
fn settle_evo_state(paths: &RunPaths, iteration: u64) -> Result<(), TrainError> {
    evogs_io::atomic::remove_interrupted(&paths.root)?;
    let own = paths.pending_evo_state(iteration);
    if own.is_file() {
        std::fs::rename(&own, paths.evo_state()).map_err(|e| TrainError::io(&own, e))?;
    }
    let entries = std::fs::read_dir(&paths.root).map_err(|e| TrainError::io(&paths.root, e))?;
    for entry in entries {
        let path = entry.map_err(|e| TrainError::io(&paths.root, e))?.path();
        let stale = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.strip_prefix(PENDING_EVO_STATE_PREFIX))
            .and_then(|n| n.strip_suffix(".safetensors"))
            .is_some_and(|i| !i.is_empty() && i.bytes().all(|b| b.is_ascii_digit()));
        if stale {
            std::fs::remove_file(&path).map_err(|e| TrainError::io(&path, e))?;
        }
    }
    Ok(())
}

/// Reads the checkpoint at `path` of a run configured by `config` into a fresh state and
/// backbone (the backbone's weights only: an EvoGS evolution state is a file of its own).
pub fn read_checkpoint(
    path: &Path,
    config: &TrainConfig,
) -> Result<(SceneState, Box<dyn Backbone>, CheckpointMeta), TrainError> {
    let mut backbone = make_backbone(config)?;
    let init = crate::init::random_gaussians(1, 1.0, config.sh_degree, 0);
    let mut state = SceneState::new(init, backbone.as_ref(), &config.lr)?;
    let meta = load_checkpoint(path, &mut state, backbone.as_mut())?;
    Ok((state, backbone, meta))
}

/// The dataset of the run whose `config.json` is `run` (the run at `paths`), when it is still
/// where the run was trained from; otherwise an error naming `config.json`'s field `data` and
/// saying how to point the run at the dataset's new place (the path is recorded as it was when
/// training started).
pub fn run_data<'a>(paths: &RunPaths, run: &'a RunFile) -> Result<&'a Path, TrainError> {
    if run.data.is_dir() {
        return Ok(&run.data);
    }
    Err(TrainError::field(
        paths.config(),
        "data",
        format!(
            "the run's dataset {} is not there (moved or deleted?); write its new location \
             into this field",
            run.data.display()
        ),
    ))
}

/// The paths of the run directory `root` and its validated `config.json`: what opening a run,
/// from its end-of-run files or its checkpoint, starts with.
pub fn read_run_file(root: &Path) -> Result<(RunPaths, RunFile), TrainError> {
    let paths = RunPaths::new(root);
    if !root.is_dir() {
        return Err(TrainError::file(root, "not a run directory"));
    }
    let run = read_run_config(&paths)?;
    Ok((paths, run))
}

/// A run's `config.json`, read and checked as a new run's settings are (every range), so that a
/// file edited by hand cannot run (or be resumed) with settings the flags would refuse; an
/// error names the file, then the setting.
fn read_run_config(paths: &RunPaths) -> Result<RunFile, TrainError> {
    let path = paths.config();
    let run: RunFile = read_json(&path)?;
    run.train.validate().map_err(|e| match e {
        TrainError::Config { field, problem } => {
            TrainError::field(&path, format!("train.{field}"), problem)
        }
        e => TrainError::file(&path, e.to_string()),
    })?;
    Ok(run)
}

/// Trains (or resumes) a run, calling `progress` after every iteration, and writes the run
/// directory. Returns the summary that `train_metrics.json` holds.
///
/// `progress` gets the trainer mutably so that it can evaluate the model in between (e.g.
/// [`Trainer::deformed_at`], which runs the backbone); it must not change the training state.
pub fn train(
    request: &TrainRequest,
    progress: &mut dyn FnMut(&StepReport, &mut Trainer),
) -> Result<TrainSummary, TrainError> {
    train_with_clock(request, None, progress)
}

/// [`train`] with the budget read from `clock` instead of the clock the run's budget names
/// (tests give a clock of made-up readings; without a budget it is not read).
pub fn train_with_clock(
    request: &TrainRequest,
    clock: Option<&mut dyn Clock>,
    progress: &mut dyn FnMut(&StepReport, &mut Trainer),
) -> Result<TrainSummary, TrainError> {
    let paths = RunPaths::new(&request.out);
    let mut resumed_budget = None;
    let mut resumed_log = None;
    let mut trainer = if request.resume {
        let mut run = read_run_config(&paths)?;
        let recorded = (run.train.backend, run.train.net_backend);
        if let Some(backend) = request.resume_backend {
            run.train.backend = backend;
        }
        if let Some(net_backend) = request.resume_net_backend {
            run.train.net_backend = net_backend;
        }
        let data = run_data(&paths, &run)?;
        let dataset = open_dataset(data, run.train.time_from)?;
        // The images and the network against the memory before either is allocated (the
        // Gaussians are checked with the rest when the trainer is made).
        let sizes = crate::memory::DataSizes::of_split(&dataset, Split::Train, run.train.downscale);
        crate::trainer::check_memory(&run.train, sizes, 0)?;
        let train = load_dataset_split(
            &dataset,
            data,
            Split::Train,
            run.train.background.rgb(),
            run.train.downscale,
        )?;
        let ckpt = paths.checkpoint();
        if !ckpt.is_file() {
            return Err(TrainError::file(
                &ckpt,
                "no checkpoint to resume from (train the run first)",
            ));
        }
        let (state, mut backbone, meta) = read_checkpoint(&ckpt, &run.train)?;
        settle_evo_state(&paths, meta.iteration)?;
        backbone.load_state(&paths.evo_state())?;
        resumed_log = meta.log;
        let mut trainer =
            Trainer::from_parts(run.train.clone(), train, state, backbone, meta.iteration)?;
        if run.train.budget.is_some() {
            let progress = meta.budget.ok_or_else(|| {
                TrainError::field(&ckpt, "budget", "missing: the run has a time budget")
            })?;
            trainer.resume_schedule_at(progress.schedule_iteration);
            resumed_budget = Some(progress);
        }
        if (run.train.backend, run.train.net_backend) != recorded {
            // Recorded only once the new backend is up, so that a failed switch changes nothing.
            write_json(&paths.config(), &run)?;
        }
        trainer
    } else {
        request.config.validate()?;
        std::fs::create_dir_all(&request.out).map_err(|e| TrainError::io(&request.out, e))?;
        // A run started again in the same directory: what a killed write left goes.
        evogs_io::atomic::remove_interrupted(&request.out)?;
        let data = std::path::absolute(&request.data).unwrap_or_else(|_| request.data.clone());
        write_json(
            &paths.config(),
            &RunFile {
                data: data.clone(),
                train: request.config.clone(),
            },
        )?;
        let c = &request.config;
        let dataset = open_dataset(&data, c.time_from)?;
        // Before the images, the network and the Gaussians are allocated.
        let sizes = crate::memory::DataSizes::of_split(&dataset, Split::Train, c.downscale);
        crate::trainer::check_memory(c, sizes, c.init_points)?;
        let train = load_dataset_split(
            &dataset,
            &data,
            Split::Train,
            c.background.rgb(),
            c.downscale,
        )?;
        // Initial points: the dataset's point cloud where it brings one (COLMAP, nerfies),
        // random in the scene box otherwise (D-NeRF practice).
        match dataset.points.as_ref().filter(|p| !p.positions.is_empty()) {
            Some(points) => Trainer::with_gaussians(
                c.clone(),
                train,
                crate::init::gaussians_from_point_cloud(points, c.sh_degree),
            )?,
            None => Trainer::new(c.clone(), train)?,
        }
    };
    let end = request.end(trainer.config());
    let mut log = TrainLog::open(
        &paths.train_log(),
        trainer.config().log_every,
        trainer.iteration(),
        resumed_log,
    )?;
    let start_iteration = trainer.iteration();
    let started = Instant::now();
    let traffic_start = trainer.traffic();
    let device_start = trainer.device_times();
    let mut last = None;
    let mut gain = trainer.new_gain_report();
    let last_quarter_from = trainer.config().iterations - trainer.config().iterations / 4;
    // A budget run: its pacer, the clock, the budget spent before this process and the clock's
    // reading when this process's loop started, less the time its callbacks took.
    let budget = trainer.config().budget;
    let mut own_clock = None;
    let mut paced = match budget {
        Some(b) => {
            let clock: &mut dyn Clock = match clock {
                Some(c) => c,
                None => own_clock.insert(clock_of(b.clock)).as_mut(),
            };
            let from = resumed_budget.unwrap_or(BudgetProgress::START);
            let pacer = Pacer::new(b.seconds, trainer.config().iterations, from);
            let origin = clock.seconds()? - from.spent_seconds;
            Some((pacer, clock, origin))
        }
        None => None,
    };
    // The run's last step was already taken (a finished budget run resumed).
    let finished = paced
        .as_ref()
        .is_some_and(|(pacer, _, _)| pacer.progress().finished);
    while trainer.iteration() < end && !finished {
        let report = match paced.as_mut() {
            None => {
                let mut report = trainer.step()?;
                report.last = report.iteration == end;
                report
            }
            Some((pacer, clock, origin)) => {
                let spent = clock.seconds()? - *origin;
                let Some(pace) = pacer.next(spent) else {
                    break;
                };
                let mut report = trainer.step_to(pace.schedule_iteration)?;
                report.last = pace.last || report.iteration == end;
                report
            }
        };
        if report.schedule_iteration > last_quarter_from
            && let Some(step) = trainer.evolution_step()
        {
            gain.add(step);
        }
        match paced.as_mut() {
            None => progress(&report, &mut trainer),
            Some((pacer, clock, origin)) => {
                // The callback's time is not the run's: the origin moves past it.
                let before = clock.seconds()?;
                progress(&report, &mut trainer);
                let after = clock.seconds()?;
                *origin += after - before;
                pacer.record(after - *origin);
            }
        }
        log.record(
            &paths.train_log(),
            report.iteration,
            report.loss,
            report.psnr,
            report.gaussians,
            trainer.backbone().gain_stats(),
            report.last,
        )?;
        let checks = report.iteration.is_multiple_of(trainer.config().log_every) || report.last;
        if checks {
            trainer.sync_host()?;
        }
        if checks && let Some((group, index)) = trainer.state().first_non_finite(trainer.backbone())
        {
            // Before the checkpoint: the last one written stays the last finite state.
            return Err(TrainError::NonFinite {
                iteration: report.iteration,
                group,
                index,
            });
        }
        if report.gaussians == 0 {
            // Before the checkpoint too: the last one written still holds Gaussians.
            return Err(TrainError::NoGaussians {
                iteration: report.iteration,
                schedule_iteration: report.schedule_iteration,
            });
        }
        // The last one is written after the loop, with the final outputs.
        let budget_progress = paced.as_ref().map(|(pacer, _, _)| pacer.progress());
        if !report.last && checkpoint_follows(trainer.config(), &report) {
            save_resumable(&paths, &mut trainer, budget_progress, &log)?;
        }
        let is_last = report.last;
        last = Some(report);
        if is_last {
            break;
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    let budget_progress = paced
        .as_ref()
        .map(|(pacer, _, _)| pacer.progress())
        .or(resumed_budget);
    save_resumable(&paths, &mut trainer, budget_progress, &log)?;
    evogs_io::write_ply(&paths.canonical(), trainer.state().gaussians().view())?;
    trainer.backbone().save(&paths.weights())?;
    let done = trainer.iteration() - start_iteration;
    let traffic_per_iteration = trainer
        .traffic()
        .zip(traffic_start)
        .map(|(end, start)| end.since(&start).per(done));
    let device_ms_per_iteration = trainer.device_times().map(|end| {
        end.into_iter()
            .map(|(label, (ms, _))| {
                let before = device_start.as_ref().and_then(|s| s.get(&label));
                let ms = ms - before.map_or(0.0, |b| b.0);
                (label, ms / done.max(1) as f64)
            })
            .collect()
    });
    let summary = TrainSummary {
        iteration: trainer.iteration(),
        iterations: trainer.config().iterations,
        iterations_this_process: done,
        seconds,
        iterations_per_second: done as f64 / seconds.max(1e-9),
        last_loss: last.map_or(f64::NAN, |r| r.loss),
        last_psnr: last.map_or(f64::NAN, |r| r.psnr),
        gaussians: trainer.state().len(),
        net_width: trainer.config().net.width,
        phases: *trainer.times(),
        gain: (gain.samples() > 0).then(|| gain.summary()),
        budget: budget
            .zip(budget_progress)
            .map(|(budget, p)| BudgetSummary::new(budget, &p)),
        traffic_per_iteration,
        device_ms_per_iteration,
        network: trainer.network().to_string(),
        loss: trainer.loss_place().to_string(),
    };
    write_json(&paths.train_metrics(), &summary)?;
    Ok(summary)
}
