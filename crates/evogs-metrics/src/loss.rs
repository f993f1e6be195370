//! The photometric training loss `0.8·L1 + 0.2·(1 − SSIM)` (DESIGN §7.1) and its exact gradient.

use rayon::prelude::*;

use crate::ssim::{SUM_CHUNK, ssim_sum_and_grad};
use crate::{ImageSize, MetricsError, Real, check_image};

/// Weight of the L1 term.
pub const L1_WEIGHT: f64 = 0.8;
/// Weight of the `1 − SSIM` term.
pub const SSIM_WEIGHT: f64 = 0.2;

/// The loss of one rendered image against its ground truth, with its gradient.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotometricLoss<T> {
    /// `0.8·l1 + 0.2·(1 − ssim)`.
    pub loss: f64,
    /// Mean absolute error over all pixels and channels.
    pub l1: f64,
    /// Mean SSIM (3DGS definition).
    pub ssim: f64,
    /// `∂loss/∂rendered`, interleaved RGB like the input. The L1 part uses `sign(0) = 0` (as
    /// PyTorch's `abs` backward does).
    pub d_rendered: Vec<[T; 3]>,
}

/// Computes `0.8·L1 + 0.2·(1 − SSIM)` of `rendered` against `gt` and its gradient with respect
/// to `rendered`.
pub fn photometric_loss<T: Real>(
    size: ImageSize,
    rendered: &[[T; 3]],
    gt: &[[T; 3]],
) -> Result<PhotometricLoss<T>, MetricsError> {
    check_image(size, rendered, "rendered")?;
    check_image(size, gt, "gt")?;
    let n = (3 * size.pixels()) as f64;
    let (ssim_sum, ssim_grad) =
        ssim_sum_and_grad(size, rendered, gt, Some(T::from_f64(-SSIM_WEIGHT / n)));
    let mut d_rendered = ssim_grad.unwrap_or_default();
    let l1_step = T::from_f64(L1_WEIGHT / n);
    let zero = T::default();
    let partial: Vec<f64> = d_rendered
        .par_chunks_mut(SUM_CHUNK)
        .zip(rendered.par_chunks(SUM_CHUNK).zip(gt.par_chunks(SUM_CHUNK)))
        .map(|(g, (r, t))| {
            let mut s = 0.0;
            for (g, (r, t)) in g.iter_mut().zip(r.iter().zip(t)) {
                for c in 0..3 {
                    let d = r[c] - t[c];
                    s += d.to_f64().abs();
                    if d > zero {
                        g[c] += l1_step;
                    } else if d < zero {
                        g[c] += -l1_step;
                    }
                }
            }
            s
        })
        .collect();
    // Added in chunk order: the same bits for any thread count.
    let l1_sum: f64 = partial.iter().sum();
    let l1 = l1_sum / n;
    let ssim = ssim_sum / n;
    Ok(PhotometricLoss {
        loss: L1_WEIGHT * l1 + SSIM_WEIGHT * (1.0 - ssim),
        l1,
        ssim,
        d_rendered,
    })
}
