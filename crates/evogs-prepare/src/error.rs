//! The one error type of the crate: each message is one line naming the file or program and
//! the problem.

use std::path::PathBuf;

use thiserror::Error;

/// Why `prepare` stopped. Nothing is left at the output path when it returns one.
#[derive(Debug, Error)]
pub enum PrepareError {
    /// A program is not installed.
    #[error(
        "{program} not found: install the Debian package `{package}` (apt-get install {package})"
    )]
    MissingTool {
        /// The program looked for on `PATH`.
        program: &'static str,
        /// The Debian package that provides it.
        package: &'static str,
    },
    /// The input (a video, an image folder) or a setting is unusable.
    #[error("{}: {problem}", path.display())]
    Input {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// An external program failed (its log is kept, see [`PrepareError::WithLogs`]).
    #[error("{}: {stage} failed: {problem}", path.display())]
    Stage {
        /// The file the stage worked on (the video, the image folder).
        path: PathBuf,
        /// The stage, e.g. `colmap mapper`.
        stage: String,
        /// The exit status and the program's last message.
        problem: String,
    },
    /// A failure after a stage ran: the error, and where the stages' logs were kept.
    #[error("{error}; the stages' logs are in {}", logs.display())]
    WithLogs {
        /// The failure.
        error: Box<PrepareError>,
        /// The folder the logs were moved to (`lib::failed_logs_dir`).
        logs: PathBuf,
    },
    /// The operating system refused a read, write, create or rename.
    #[error("{}: {cause}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What the operating system said.
        cause: std::io::Error,
    },
    /// The reconstruction could not be read back or does not load as a dataset.
    #[error(transparent)]
    Dataset(#[from] evogs_io::IoError),
}

impl PrepareError {
    pub(crate) fn io(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            cause,
        }
    }

    pub(crate) fn input(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Self::Input {
            path: path.into(),
            problem: problem.into(),
        }
    }
}
