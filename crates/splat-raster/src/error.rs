//! The rasterizer's error type: bad input is reported with the field it came from, never a panic.

use thiserror::Error;

/// Why a forward or backward pass refused its input.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RasterError {
    /// A per-Gaussian array does not have the length the means imply.
    #[error("Gaussians: {field} has {got} entries, expected {expected}")]
    LengthMismatch {
        /// The offending field of `GaussiansView`.
        field: &'static str,
        /// Its length.
        got: usize,
        /// The length implied by the number of means and the SH degree.
        expected: usize,
    },
    /// The data's SH degree is above 3.
    #[error("Gaussians: sh_degree is {0}, the rasterizer supports 0..=3")]
    ShDegree(u32),
    /// `RenderOptions::sh_degree` asks for more bands than the data holds.
    #[error("RenderOptions: sh_degree {requested} is above the data's SH degree {available}")]
    ActiveShDegree {
        /// The requested number of active bands.
        requested: u32,
        /// The data's SH degree.
        available: u32,
    },
    /// The camera has a zero width or height.
    #[error("Camera: image size {width}x{height} has no pixels")]
    EmptyImage {
        /// Camera width.
        width: u32,
        /// Camera height.
        height: u32,
    },
    /// A camera field is non-finite or out of range.
    #[error("Camera: {field} is {value}, {why}")]
    BadCamera {
        /// The offending camera field.
        field: &'static str,
        /// Its value (the first bad component for matrices and vectors).
        value: f32,
        /// What is required of it.
        why: &'static str,
    },
    /// The background colour holds a non-finite value.
    #[error("RenderOptions: background channel {channel} is {value}, must be finite")]
    BadBackground {
        /// Channel index 0..3.
        channel: usize,
        /// Its value.
        value: f32,
    },
    /// A gradient image passed to the backward pass has the wrong length.
    #[error("backward: {field} has {got} pixels, expected {expected}")]
    GradientLength {
        /// `d_color`, `d_alpha` or `d_depth`.
        field: &'static str,
        /// Its length.
        got: usize,
        /// `width * height` of the forward output.
        expected: usize,
    },
    /// A gradient image passed to the backward pass holds NaN or infinity.
    #[error("backward: {field} holds a non-finite value at pixel {pixel}")]
    NonFiniteGradient {
        /// `d_color`, `d_alpha` or `d_depth`.
        field: &'static str,
        /// Row-major pixel index.
        pixel: usize,
    },
    /// The forward output handed to the backward pass was made from other inputs.
    #[error("backward: the forward output does not match the inputs ({0})")]
    ForwardMismatch(String),
    /// The GPU backend could not run: no adapter, a refused device, a buffer beyond the device's
    /// limits, or a failed read-back.
    #[error("wgpu backend ({stage}): {message}")]
    Gpu {
        /// Where it failed: `adapter`, `device` (an error the device reported while running),
        /// `pipelines`, `buffers`, `read-back` or `resident` (a resident pass asked of a backend
        /// without a device).
        stage: &'static str,
        /// What went wrong.
        message: String,
    },
    /// A backend name that is not `cpu`, `wgpu` or `auto` ("unknown backend `x`; expected cpu,
    /// wgpu or auto"; the error of `BackendChoice`'s `from_str`, which writes the message).
    #[error("{message}")]
    UnknownBackend {
        /// The name asked for.
        name: String,
        /// The whole line.
        message: String,
    },
    /// A thread pool could not be built.
    #[error("could not build a thread pool of {threads} threads: {message}")]
    ThreadPool {
        /// The requested thread count.
        threads: usize,
        /// Rayon's message.
        message: String,
    },
}

#[cfg(feature = "wgpu")]
impl From<gpu_core::GpuError> for RasterError {
    fn from(e: gpu_core::GpuError) -> Self {
        RasterError::Gpu {
            stage: e.stage,
            message: e.message,
        }
    }
}
