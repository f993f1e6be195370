//! Errors of scene generation and writing.

use std::path::PathBuf;

use thiserror::Error;

/// Why a scene could not be generated or written.
#[derive(Debug, Error)]
pub enum SynthError {
    /// A field of the [`SceneSpec`](super::SceneSpec) is out of range.
    #[error("scene spec field `{field}`: {problem}")]
    Spec {
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// Rendering a frame failed.
    #[error("rendering {split} frame {index}: {source}")]
    Render {
        /// Split name.
        split: &'static str,
        /// Frame index in the split.
        index: usize,
        /// The rasterizer's error.
        source: splat_raster::RasterError,
    },
    /// A file could not be written.
    #[error(transparent)]
    Io(#[from] evogs_io::IoError),
    /// A ground-truth file is malformed.
    #[error("{path}: tensor `{field}`: {problem}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// The tensor (or `header`).
        field: String,
        /// What is wrong.
        problem: String,
    },
    /// A file's content could not be encoded.
    #[error("{path}: {problem}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// What failed.
        problem: String,
    },
}
