//! `evogs-train`: the training pipeline for dynamic Gaussian scenes.
//!
//! What it is: the composition of the workspace's crates into a trainer (scene state kept aligned
//! through densify's row plans, the deformation backbones of `evogs-backbones`, losses,
//! schedules, checkpoints).
//!
//! - [`config`]: the D-3DGS recipe and the presets (`paper`, `cpu`, `tiny`); the run's whole
//!   config, which embeds the backbones' settings (`evogs_backbones::NetSettings`,
//!   `evogs_backbones::EvoSettings`);
//! - [`state`]: canonical Gaussians, Adam groups and statistics, aligned through densify's plans;
//! - [`trainer`]: the training loop and [`trainer::make_backbone`] (the backbone a config asks
//!   for); [`run`]: run directories (their layout, atomic JSON files, the config and checkpoint
//!   read back), `train` and resume;
//! - [`checkpoint`]: exact checkpoints;
//! - [`budget`]: time budgets (`--time-budget`): the schedule's position from the budget spent;
//! - [`gain_report`]: K's distribution (overall, moving vs still, per frame), accumulated by the
//!   run and saved in `train_metrics.json` (its table and the motion report, a diagnostic of
//!   EvoGS's motion statistics, are in `evogs-experiments`);
//! - [`train_log`]: `train_log.jsonl` (its plot, `evogs plot`, is in `evogs-experiments`).
//!
//! The recipe follows Deformable-3D-Gaussians (`ingra14m/Deformable-3D-Gaussians`: `train.py`,
//! `arguments/__init__.py`, `scene/deform_model.py`, `utils/time_utils.py`) and 3DGS's
//! `scene/gaussian_model.py`; each module says what it follows.
//!
//! What it is not: a rasterizer, a network library, a deformation backbone, a file-format
//! reader, a metrics library, the evaluation, rendering and export of a finished run, a scene
//! generator, an experiment or a plot (ablation ladder, benchmark, training plot), camera paths
//! and videos, or a command line. Those are `splat-raster`, `tiny-nn`, `evogs-backbones`,
//! `evogs-io`, `evogs-metrics`, `evogs-eval`, `evogs-synth`, `evogs-experiments`, `evogs-video`
//! and `evogs-cli`.

pub mod budget;
pub mod checkpoint;
pub mod config;
pub mod data;
#[cfg(feature = "wgpu")]
mod device_loss;
pub mod error;
pub mod gain_report;
pub mod init;
pub mod memory;
pub mod run;
mod run_files;
pub mod state;
pub mod timers;
pub mod train_log;
pub mod trainer;

pub use config::{BackboneKind, Background, Method, Preset, TrainConfig};
pub use error::TrainError;
pub use run::{RunPaths, TrainRequest, TrainSummary, train};
pub use trainer::{Placement, StepReport, Trainer};
