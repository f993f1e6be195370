//! Errors of LPIPS: weights not installed or malformed, images the network cannot take.

use std::path::PathBuf;

use thiserror::Error;

use super::Backbone;
use crate::MetricsError;

/// Why LPIPS could not be loaded or computed.
#[derive(Debug, Error)]
pub enum LpipsError {
    /// No weights file where the search order led.
    #[error(
        "LPIPS {backbone} weights not found at {}; install them with `scripts/lpips-weights` (evogs repository)",
        path.display()
    )]
    Missing {
        /// The backbone asked for.
        backbone: Backbone,
        /// The file looked for.
        path: PathBuf,
    },
    /// The weights file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The weights file is not what `scripts/lpips-weights` writes.
    #[error("{}: `{field}`: {msg}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// The tensor (or `header`) at fault.
        field: String,
        /// What is wrong with it.
        msg: String,
    },
    /// An image side is below the network's minimum.
    #[error("LPIPS {backbone} needs images of at least {min}x{min} pixels, got {width}x{height}")]
    TooSmall {
        /// The backbone.
        backbone: Backbone,
        /// Smallest side the backbone takes.
        min: usize,
        /// Width given.
        width: usize,
        /// Height given.
        height: usize,
    },
    /// An image of a pair is malformed (pixel count, NaN/Inf).
    #[error(transparent)]
    Image(#[from] MetricsError),
}
