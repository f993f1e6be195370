//! The crate's error type.

use std::path::PathBuf;

/// Everything that can go wrong in this crate. Bad input never panics; it is one of these.
#[derive(Debug, thiserror::Error)]
pub enum NnError {
    /// A slice does not have the length its shape requires.
    #[error("{what}: expected {expected} values, got {got}")]
    Shape {
        /// Which argument.
        what: String,
        /// Required length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// A configuration value is out of range.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A weights file is malformed or does not match the network.
    #[error("{path}: {field}: {msg}")]
    File {
        /// The file.
        path: PathBuf,
        /// The tensor or header field at fault.
        field: String,
        /// What is wrong.
        msg: String,
    },
    /// The device refused or failed a network's work (cargo feature `wgpu`).
    #[cfg(feature = "wgpu")]
    #[error("gpu: {0}")]
    Gpu(#[from] gpu_core::GpuError),
}

/// Checks `got == expected` for the argument `what`.
pub(crate) fn check_len(what: &str, expected: usize, got: usize) -> Result<(), NnError> {
    if expected == got {
        Ok(())
    } else {
        Err(NnError::Shape {
            what: what.to_string(),
            expected,
            got,
        })
    }
}
