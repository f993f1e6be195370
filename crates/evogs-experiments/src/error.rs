//! The one error type of the crate. Every message is one line that names the file (or the setting)
//! it is about; errors of training and evaluation pass through unchanged.

use std::path::PathBuf;

use evogs_train::TrainError;
use thiserror::Error;

/// An error of an experiment: a bad request, an output that could not be written, or an error of
/// the training core.
#[derive(Debug, Error)]
pub enum ExperimentError {
    /// Training, evaluation or rendering failed (names the file when there is one).
    #[error(transparent)]
    Train(#[from] TrainError),
    /// A file format error from `evogs-io` (names the file).
    #[error(transparent)]
    Io(#[from] evogs_io::IoError),
    /// A metric of the benchmark's curve could not be computed.
    #[error("metrics: {0}")]
    Metrics(#[from] evogs_metrics::MetricsError),
    /// An output directory could not be created.
    #[error("{}: {cause}", path.display())]
    Dir {
        /// The directory.
        path: PathBuf,
        /// Why.
        cause: std::io::Error,
    },
    /// An output file (table, JSON, plot) could not be produced.
    #[error("{}: {problem}", path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// A file the experiment reads (a run's record) could not be read or parsed.
    #[error("{}: {problem}", path.display())]
    Input {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// A setting of the request is out of range or unknown.
    #[error("invalid setting `{field}`: {problem}")]
    Config {
        /// The setting.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

impl ExperimentError {
    pub(crate) fn config(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self::Config {
            field: field.into(),
            problem: problem.into(),
        }
    }

    pub(crate) fn output(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Self::Output {
            path: path.into(),
            problem: problem.into(),
        }
    }

    pub(crate) fn input(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Self::Input {
            path: path.into(),
            problem: problem.into(),
        }
    }

    pub(crate) fn dir(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        Self::Dir {
            path: path.into(),
            cause,
        }
    }
}
