//! Errors of the evolution state.

use std::path::PathBuf;

use thiserror::Error;

use crate::config::ConfigError;
use crate::frames::FramesError;
use splat_core::RowPlanError;

/// Anything that can go wrong in a step, a row plan, or saving/loading.
#[derive(Debug, Error)]
pub enum EvoError {
    /// The configuration is out of range.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The training frame times are unusable.
    #[error(transparent)]
    Frames(#[from] FramesError),
    /// A row plan does not fit the state's arrays.
    #[error(transparent)]
    RowPlan(#[from] RowPlanError),
    /// The gain network Ψ failed (shape errors from tiny-nn).
    #[error("gain network: {0}")]
    Network(#[from] tiny_nn::NnError),
    /// An input array has the wrong length.
    #[error("{what}: expected {expected} values, got {actual}")]
    Length {
        /// The array (e.g. `observation z`).
        what: &'static str,
        /// The length the Gaussian count and D imply.
        expected: usize,
        /// Its length.
        actual: usize,
    },
    /// A non-finite value in an input array, naming the Gaussian (row) and the component.
    #[error("{what}: non-finite value {value} at Gaussian {row}, component {component}")]
    NonFinite {
        /// The array.
        what: &'static str,
        /// The Gaussian.
        row: usize,
        /// The column within the row (0..D).
        component: usize,
        /// The value (NaN or ±∞).
        value: f32,
    },
    /// The query time is not finite.
    #[error("query time {0} is not finite")]
    NonFiniteTime(f32),
    /// The scene extent a residual is measured against is not a finite positive number.
    #[error("extent: scene extent {0} must be finite and positive")]
    Extent(f32),
    /// Only training steps (at a frame time) commit.
    #[error("time {0} is not a training frame time; only training steps commit")]
    NotAFrame(f32),
    /// The step was computed before a row plan changed the Gaussian set.
    #[error(
        "step was computed for {step_rows} Gaussians (generation {step_generation}), the state now has {rows} (generation {generation})"
    )]
    StaleStep {
        /// Gaussians when the step was computed.
        step_rows: usize,
        /// The state's generation (row plans applied) when the step was computed.
        step_generation: u64,
        /// Gaussians now.
        rows: usize,
        /// The generation now.
        generation: u64,
    },
    /// History re-query mode needs an observation source.
    #[error("history mode Requery needs an observation source (use forward_with)")]
    NeedsObservationSource,
    /// The observation source failed.
    #[error("observation source failed at time {time}: {source}")]
    Source {
        /// The history time Φ was queried at.
        time: f32,
        /// The source's error.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A saved state is malformed.
    #[error("{}: field `{field}`: {problem}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// The tensor or metadata key at fault.
        field: String,
        /// What is wrong with it.
        problem: String,
    },
}
