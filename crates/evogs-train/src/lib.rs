//! `evogs-train`: the training pipeline for dynamic Gaussian scenes.
//!
//! What it is: the composition of the workspace's crates into a trainer (scene state kept aligned
//! through densify's row plans, deformation backbones, losses, schedules, checkpoints).
//!
//! - [`config`]: the D-3DGS recipe and the presets (`paper`, `cpu`, `tiny`);
//! - [`backbone`]: the deformation-backbone traits (the core, and the optional per-Gaussian
//!   state) and the D-3DGS backbone;
//! - [`evo_backbone`], [`evo_settings`]: EvoGS (Φ + evo-state + Ψ) and its switches;
//! - [`state`]: canonical Gaussians, Adam groups and statistics, aligned through densify's plans;
//! - [`trainer`]: the training loop; [`run`]: run directories, `train` and resume;
//! - [`checkpoint`]: exact checkpoints; [`eval`], [`render`]: evaluation, rendering, export;
//! - [`gain_report`]: K's distribution (overall, moving vs still, per frame), accumulated by the
//!   run and saved in `train_metrics.json` (its table and the motion report, a diagnostic of
//!   EvoGS's motion statistics, are in `evogs-experiments`);
//! - [`train_log`]: `train_log.jsonl` (its plot, `evogs plot`, is in `evogs-experiments`).
//!
//! The recipe follows Deformable-3D-Gaussians (`ingra14m/Deformable-3D-Gaussians`: `train.py`,
//! `arguments/__init__.py`, `scene/deform_model.py`, `utils/time_utils.py`) and 3DGS's
//! `scene/gaussian_model.py`; each module says what it follows.
//!
//! Deliberate deviation from the paper (DESIGN §4.7): EvoGS's motion floor is 1e-3 of the scene extent per frame
//! spacing, not 1e-6 (evo-state keeps 1e-6; the trainer sets its own, `--motion-floor`).
//! Below it θ is measurement noise that would block the uncertainty trigger everywhere; see
//! [`evo_settings::TRAINER_MOTION_FLOOR`] for the measurement and the reasoning.
//!
//! What it is not: a rasterizer, a network library, a file-format reader, a metrics library, a scene
//! generator, an experiment or a plot (ablation ladder, benchmark, training plot), camera paths
//! and videos, or a command line. Those are `splat-raster`, `tiny-nn`, `evogs-io`,
//! `evogs-metrics`, `evogs-synth`, `evogs-experiments`, `evogs-video` and `evogs-cli`.

pub mod backbone;
pub mod checkpoint;
pub mod config;
pub mod data;
pub mod deformed;
pub mod error;
pub mod eval;
pub mod evo_backbone;
pub mod evo_settings;
pub mod gain_report;
pub mod hex_backbone;
pub mod init;
pub mod memory;
pub mod render;
pub mod run;
pub mod state;
pub mod timers;
pub mod train_log;
pub mod trainer;

pub use backbone::{Backbone, D3dgsBackbone, DEFORM_DIM, DensifyCues, PerGaussianState};
pub use config::{BackboneKind, Background, Method, Preset, TrainConfig};
pub use error::TrainError;
pub use evo_backbone::EvoBackbone;
pub use evo_settings::{DensifyPolicy, EvoSettings, Gain, HistoryMode, Layout, Precision, Storage};
pub use hex_backbone::HexBackbone;
pub use run::{LoadedRun, RunPaths, TrainRequest, TrainSummary, train};
pub use trainer::{StepReport, Trainer};
