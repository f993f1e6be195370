//! The one error type of the crate. Every message is one line that names the file (and the field)
//! it is about when there is one.

use std::path::PathBuf;

use splat_core::one_word::{OneWord, unknown_message};
use thiserror::Error;

/// An error of training, evaluation, rendering or export.
#[derive(Debug, Error)]
pub enum TrainError {
    /// A file format error from `evogs-io` (names the file and the field).
    #[error(transparent)]
    Io(#[from] evogs_io::IoError),
    /// The rasterizer rejected its input.
    #[error("rasterizer: {0}")]
    Raster(#[from] splat_raster::RasterError),
    /// A backbone's error (its messages are the trainer's own).
    #[error(transparent)]
    Backbone(#[from] evogs_backbones::BackboneError),
    /// A network or optimiser error.
    #[error("network: {0}")]
    Nn(#[from] tiny_nn::NnError),
    /// A densification error.
    #[error(transparent)]
    Densify(#[from] densify::DensifyError),
    /// A metric could not be computed.
    #[error("metrics: {0}")]
    Metrics(#[from] evogs_metrics::MetricsError),
    /// LPIPS weights are malformed, or an image is too small for its network.
    #[error(transparent)]
    Lpips(#[from] evogs_metrics::lpips::LpipsError),
    /// A file of a run (config, checkpoint, weights) or a dataset is unusable.
    #[error("{}: {problem}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A field of a file has a bad value.
    #[error("{}: field `{field}`: {problem}", path.display())]
    Field {
        /// The file.
        path: PathBuf,
        /// The field.
        field: String,
        /// What is wrong.
        problem: String,
    },
    /// A parameter became NaN or infinite during training (checked every log interval).
    #[error(
        "iteration {iteration}: `{group}` holds a non-finite value (NaN or infinity) at index {index}; \
         the run stopped (resume from the last checkpoint with a lower learning rate)"
    )]
    NonFinite {
        /// The iteration after which it was found.
        iteration: u64,
        /// The parameter group.
        group: String,
        /// Index of the first non-finite value in the group.
        index: usize,
    },
    /// Densification pruned every Gaussian: nothing is left to train or render, and clone and
    /// split cannot bring any back, so the run stops instead of spending its schedule (or its
    /// budget) on an empty scene.
    #[error(
        "iteration {iteration} (schedule iteration {schedule_iteration}): densification pruned \
         every Gaussian, nothing is left to train; the run stopped (its last checkpoint, if one \
         was written, holds an earlier state). The schedule may be compressed too far: a larger --iterations leaves \
         more steps between densifications"
    )]
    NoGaussians {
        /// The iteration after which none were left.
        iteration: u64,
        /// Its schedule iteration (the iteration, without a time budget).
        schedule_iteration: u64,
    },
    /// A setting is out of range or unsupported.
    #[error("invalid setting `{field}`: {problem}")]
    Config {
        /// The setting.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

impl TrainError {
    /// A [`TrainError::File`] error: `path` and what is wrong with it.
    pub fn file(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Self::File {
            path: path.into(),
            problem: problem.into(),
        }
    }

    /// A [`TrainError::Field`] error: the file, its field and what is wrong with it.
    pub fn field(
        path: impl Into<PathBuf>,
        field: impl Into<String>,
        problem: impl Into<String>,
    ) -> Self {
        Self::Field {
            path: path.into(),
            field: field.into(),
            problem: problem.into(),
        }
    }

    /// A [`TrainError::Config`] error: the setting and what is wrong with it.
    pub fn config(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self::Config {
            field: field.into(),
            problem: problem.into(),
        }
    }

    pub(crate) fn io(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        Self::File {
            path: path.into(),
            problem: cause.to_string(),
        }
    }
}

/// [`unknown_message`] as the error of the setting [`OneWord::FIELD`] (the `parse_err_fn` of the
/// trainer's one-word settings).
pub(crate) fn unknown<T: OneWord>(value: &str) -> TrainError {
    TrainError::config(T::FIELD, unknown_message::<T>(value))
}
