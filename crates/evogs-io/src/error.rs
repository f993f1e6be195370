//! The one error type of the crate: every variant names the file it is about.

use std::path::PathBuf;

use thiserror::Error;

use crate::ply::PlyProblem;

/// An error reading or writing a file. Its message starts with the file's path and names the
/// field or the problem, so it can be shown to a user as one line.
#[derive(Debug, Error)]
pub enum IoError {
    /// The operating system refused a read, write, create or rename.
    #[error("{}: {cause}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// A PLY file is malformed or unsupported.
    #[error("{}: {problem}", path.display())]
    Ply {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        problem: PlyProblem,
    },
    /// A JSON file does not parse.
    #[error("{}: invalid JSON: {cause}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The parser's message (with line and column).
        cause: serde_json::Error,
    },
    /// A field of a JSON file is missing or has a bad value.
    #[error("{}: field `{field}`: {problem}", path.display())]
    Field {
        /// The file.
        path: PathBuf,
        /// The field, as a path such as `frames[3].transform_matrix`.
        field: String,
        /// What is wrong with it.
        problem: String,
    },
    /// An image cannot be decoded or encoded.
    #[error("{}: {cause}", path.display())]
    Image {
        /// The file.
        path: PathBuf,
        /// The image library's message.
        cause: image::ImageError,
    },
    /// Data handed to a writer is inconsistent (mismatched lengths, bad sizes).
    #[error("{}: cannot write: {problem}", path.display())]
    InvalidData {
        /// The file that was to be written.
        path: PathBuf,
        /// What is inconsistent.
        problem: String,
    },
}

impl IoError {
    pub(crate) fn io(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            cause,
        }
    }

    pub(crate) fn field(
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

    /// The same error about `path` instead (a staged file's error as one about its target).
    #[must_use]
    pub fn with_path(mut self, new: impl Into<PathBuf>) -> Self {
        match &mut self {
            Self::Io { path, .. }
            | Self::Ply { path, .. }
            | Self::Json { path, .. }
            | Self::Field { path, .. }
            | Self::Image { path, .. }
            | Self::InvalidData { path, .. } => *path = new.into(),
        }
        self
    }

    /// The file the error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            Self::Io { path, .. }
            | Self::Ply { path, .. }
            | Self::Json { path, .. }
            | Self::Field { path, .. }
            | Self::Image { path, .. }
            | Self::InvalidData { path, .. } => path,
        }
    }
}
