//! `evogs-eval`: a trained run read back and put to use.
//!
//! What it is:
//! - [`loaded`]: [`LoadedRun`], a run directory written by `evogs_train::train` read back (from
//!   its end-of-run files, or from the checkpoint of a run still training), with the backbone's
//!   weights and state and the rasterizer to render with;
//! - [`eval`]: evaluation on a split (per-image PSNR, SSIM and LPIPS, fixed-camera flicker and
//!   trajectory jitter; DESIGN §8), written as `eval_<split>.json` and a markdown table;
//! - [`render`]: rendering from any camera at any time, time sweeps, and export of a frame's
//!   deformed Gaussians (PLY, compressed PLY, `.splat`) or of a sequence.
//!
//! Everything here only reads a run (and writes its evaluation and exports): nothing in the
//! training core calls it.
//!
//! What it is not: training or resuming (`evogs-train`, which also owns the run directory's
//! layout, `RunPaths`, and its files), the metrics themselves (`evogs-metrics`), camera paths and
//! videos (`evogs-video`), the viewer (`evogs-view`) or a command line (`evogs-cli`).

pub mod eval;
pub mod loaded;
pub mod render;

pub use loaded::LoadedRun;
