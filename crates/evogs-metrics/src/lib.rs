//! `evogs-metrics`: the image and temporal metrics shared by training and evaluation (DESIGN §7.1, §8).
//!
//! - [`psnr`] and [`mse`]: per image, over RGB in `[0, 1]`.
//! - [`ssim`]: 3DGS's SSIM (`utils/loss_utils.py`): 11×11 Gaussian window, σ = 1.5, C1 = 0.01²,
//!   C2 = 0.03², per channel, convolution with **zero padding** to the same size (as
//!   `F.conv2d(..., padding=5)` does there), averaged over every pixel and channel.
//! - [`photometric_loss`]: the training loss `0.8·L1 + 0.2·(1 − SSIM)` and its exact gradient
//!   with respect to the rendered image (analytic SSIM backward through the separable Gaussian
//!   convolutions). Generic over [`Real`] so the same code runs in f32 (training) and f64 (the
//!   finite-difference checks).
//! - [`LossWorkspace`]: the same loss and gradient (and the MSE), fast and allocation-free, for
//!   the training loop; [`photometric_loss`] is its plain reference.
//! - [`flicker`] and [`trajectory_jitter`]: the temporal consistency metrics.
//! - [`lpips`]: LPIPS with the AlexNet or VGG16 backbone from the published weights.
//! - `gpu` (cargo feature `wgpu`): the training loss and its gradient in WGSL kernels, checked
//!   against [`LossWorkspace`] and [`photometric_loss`].
//!
//! Images are row-major `[r, g, b]` slices (`index = y * width + x`), as `splat-raster` renders
//! them.
//!
//! What it is not: a renderer, a trainer or an image reader. Metrics take plain slices; the only
//! workspace crates it depends on are `tiny-nn`, whose matrix product runs LPIPS's convolutions,
//! and, with the feature `wgpu`, `gpu-core` for the GPU loss.

mod error;
mod fast_loss;
mod gaussian_blur;
#[cfg(feature = "wgpu")]
pub mod gpu;
mod loss;
pub mod lpips;
mod psnr;
mod real;
mod ssim;
mod temporal;

pub use error::MetricsError;
pub use fast_loss::{LossValues, LossWorkspace};
pub use gaussian_blur::{SSIM_SIGMA, SSIM_WINDOW, ssim_kernel};
pub use loss::{L1_WEIGHT, PhotometricLoss, SSIM_WEIGHT, photometric_loss};
pub use psnr::{mse, psnr, psnr_from_mse};
pub use real::Real;
pub use ssim::{SSIM_C1, SSIM_C2, ssim};
pub use temporal::{Flicker, Jitter, flicker, trajectory_jitter};

/// Width and height of an image in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageSize {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

impl ImageSize {
    /// An image size.
    pub fn new(width: usize, height: usize) -> Self {
        Self { width, height }
    }

    /// Number of pixels.
    pub fn pixels(self) -> usize {
        self.width * self.height
    }
}

/// Checks that `image` has `size.pixels()` finite pixels; `name` names it in the error.
pub(crate) fn check_image<T: Real>(
    size: ImageSize,
    image: &[[T; 3]],
    name: &'static str,
) -> Result<(), MetricsError> {
    if size.width == 0 || size.height == 0 {
        return Err(MetricsError::EmptyImage {
            width: size.width,
            height: size.height,
        });
    }
    if image.len() != size.pixels() {
        return Err(MetricsError::PixelCount {
            image: name,
            got: image.len(),
            expected: size.pixels(),
        });
    }
    if let Some(index) = image
        .iter()
        .position(|p| p.iter().any(|v| !v.to_f64().is_finite()))
    {
        return Err(MetricsError::NonFinite { image: name, index });
    }
    Ok(())
}
