//! Errors of the metrics: mismatched or malformed inputs, named by the argument they came from.

use thiserror::Error;

/// Why a metric could not be computed.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum MetricsError {
    /// The image size has a zero side.
    #[error("image size {width}x{height} has no pixels")]
    EmptyImage {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// An image does not hold `width * height` pixels.
    #[error("image `{image}` has {got} pixels, expected {expected}")]
    PixelCount {
        /// Which argument.
        image: &'static str,
        /// Pixels given.
        got: usize,
        /// Pixels the size implies.
        expected: usize,
    },
    /// A pixel holds NaN or an infinity.
    #[error("image `{image}` has a non-finite value at pixel {index}")]
    NonFinite {
        /// Which argument.
        image: &'static str,
        /// Row-major pixel index.
        index: usize,
    },
    /// Two sequences that must be aligned have different lengths.
    #[error("`{field}` has {got} entries, expected {expected}")]
    Length {
        /// Which argument (and, for nested data, which frame).
        field: String,
        /// Entries given.
        got: usize,
        /// Entries expected.
        expected: usize,
    },
    /// A position holds NaN or an infinity.
    #[error("`{field}` has a non-finite position at frame {frame}, Gaussian {index}")]
    NonFinitePosition {
        /// Which argument.
        field: &'static str,
        /// Frame index.
        frame: usize,
        /// Gaussian index.
        index: usize,
    },
}
