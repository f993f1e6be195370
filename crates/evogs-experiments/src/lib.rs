//! `evogs-experiments`: the experiment layer built on the training core.
//!
//! - [`ablate`], [`ablate_plot`]: the paper's ablation ladder at equal iterations on one dataset
//!   (rows, runner, `ablation.md`/`.json`/`.png`), and [`ablate::train_and_evaluate`], the
//!   one-method piece `evogs demo` shares;
//! - [`bench`](mod@bench), [`bench_plot`]: the D-NeRF benchmark (scenes × methods, table with the published
//!   figures, PSNR-against-time plot, pictures);
//! - [`motion_report`]: a diagnostic of EvoGS's motion statistics during training (speeds and θ
//!   by decade; `evogs train --motion-report`); [`gain_table`]: the table of K's distribution
//!   that the run accumulates (`evogs train --gain-report`);
//! - [`train_plot`]: the training plot of `evogs plot` (from `train_log.jsonl`);
//!   [`plotting`]: what the plots share (text-less fallback, axis ranges);
//! - [`error`]: [`ExperimentError`], the crate's one error type.
//!
//! What it is not: the trainer, the evaluator or a metric. Those are `evogs-train`, `evogs-eval`
//! and `evogs-metrics`; this crate only composes them into experiments.

pub mod ablate;
mod ablate_data;
pub mod ablate_plot;
pub mod bench;
mod bench_data;
pub mod bench_plot;
pub mod error;
pub mod gain_table;
pub mod motion_report;
pub mod plotting;
pub mod train_plot;
mod write;

pub use error::ExperimentError;
