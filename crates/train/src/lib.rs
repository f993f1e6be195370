//! `evogs-train`: the training pipeline for dynamic Gaussian scenes.
//!
//! What it is: the composition of the workspace's crates into a trainer (scene state kept aligned
//! through densify's row plans, deformation backbones, losses, schedules, checkpoints), synthetic
//! scene generation, and the image and temporal metrics shared by training and evaluation.
//!
//! What it is not: a rasterizer, a network library, a file-format reader or a command line. Those
//! are `splat-raster`, `tiny-nn`, `evogs-io` and `evogs-cli`.

pub mod metrics;
pub mod synth;
