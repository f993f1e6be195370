//! The crate's error type: what stops the viewer from starting. Problems of single requests are
//! HTTP responses, not errors of this type.

use thiserror::Error;

/// Why the viewer could not start (or a run could not be loaded).
#[derive(Debug, Error)]
pub enum ViewError {
    /// A run could not be loaded (names the file and the field).
    #[error(transparent)]
    Run(#[from] evogs_train::TrainError),
    /// The listening socket could not be opened.
    #[error("cannot listen on {addr}: {cause}")]
    Bind {
        /// The address asked for.
        addr: String,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// An option is out of range.
    #[error("invalid option `{option}`: {problem}")]
    Option {
        /// The option.
        option: &'static str,
        /// What is wrong.
        problem: String,
    },
    /// A thread of the viewer stopped unexpectedly.
    #[error("viewer thread stopped: {0}")]
    Thread(String),
}
