//! The one error type of the crate. Every message is one line that names the file (and the field)
//! or the setting it is about; the trainer's `TrainError` wraps it unchanged.

use std::path::PathBuf;

use thiserror::Error;

/// An error of a backbone or of its settings.
#[derive(Debug, Error)]
pub enum BackboneError {
    /// A network or optimiser error.
    #[error("network: {0}")]
    Nn(#[from] tiny_nn::NnError),
    /// A densification error.
    #[error(transparent)]
    Densify(#[from] densify::DensifyError),
    /// The evolution state refused a setting, an input or a step (a non-finite observation
    /// names its Gaussian and component).
    #[error("evolution state: {0}")]
    Evo(#[from] evo_state::EvoError),
    /// A weights or state file is unusable (the message names the field where there is one).
    #[error("{}: {problem}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
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

impl BackboneError {
    /// A [`BackboneError::File`] error: `path` and what is wrong with it.
    pub fn file(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Self::File {
            path: path.into(),
            problem: problem.into(),
        }
    }

    /// A [`BackboneError::Config`] error: the setting and what is wrong with it.
    pub fn config(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self::Config {
            field: field.into(),
            problem: problem.into(),
        }
    }
}
