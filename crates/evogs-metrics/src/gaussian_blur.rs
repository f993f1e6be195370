//! The separable Gaussian window of SSIM and its zero-padded "same" convolution.
//!
//! 3DGS builds the 11×11 window as the outer product of a normalised 1D Gaussian
//! `g[k] ∝ exp(-(k - 5)² / (2σ²))` and convolves with `padding = 5`, i.e. pixels outside the image
//! count as zero. The window is symmetric, so this convolution is its own adjoint, which the
//! backward pass uses.

use rayon::prelude::*;

use crate::Real;

/// Side of the SSIM window in pixels.
pub const SSIM_WINDOW: usize = 11;
/// Standard deviation of the SSIM window in pixels.
pub const SSIM_SIGMA: f64 = 1.5;

const RADIUS: usize = SSIM_WINDOW / 2;

/// The normalised 1D Gaussian of the SSIM window (sums to 1).
pub fn ssim_kernel() -> [f64; SSIM_WINDOW] {
    let mut k = [0.0; SSIM_WINDOW];
    for (i, v) in k.iter_mut().enumerate() {
        let d = i as f64 - RADIUS as f64;
        *v = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let sum: f64 = k.iter().sum();
    for v in &mut k {
        *v /= sum;
    }
    k
}

/// The kernel in the working precision.
pub(crate) fn kernel_in<T: Real>() -> [T; SSIM_WINDOW] {
    ssim_kernel().map(T::from_f64)
}

/// Blurs a `width × height` plane with the separable window, zero padding, same size.
/// Rows are processed in parallel.
pub(crate) fn blur<T: Real>(
    plane: &[T],
    width: usize,
    height: usize,
    kernel: &[T; SSIM_WINDOW],
) -> Vec<T> {
    debug_assert_eq!(plane.len(), width * height);
    // Horizontal pass.
    let mut horizontal = vec![T::default(); width * height];
    horizontal
        .par_chunks_mut(width)
        .zip(plane.par_chunks(width))
        .for_each(|(out, row)| blur_row(row, out, kernel));
    // Vertical pass: each output row is a weighted sum of up to 11 input rows.
    let mut out = vec![T::default(); width * height];
    out.par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, out_row)| {
            let lo = y.saturating_sub(RADIUS);
            let hi = (y + RADIUS).min(height - 1);
            for src_y in lo..=hi {
                let w = kernel[src_y + RADIUS - y];
                let src = &horizontal[src_y * width..(src_y + 1) * width];
                for (o, &s) in out_row.iter_mut().zip(src) {
                    *o += w * s;
                }
            }
        });
    out
}

/// One row of the horizontal pass (zero padding).
fn blur_row<T: Real>(row: &[T], out: &mut [T], kernel: &[T; SSIM_WINDOW]) {
    let width = row.len();
    let interior = RADIUS..width.saturating_sub(RADIUS);
    for (x, o) in out.iter_mut().enumerate() {
        let mut acc = T::default();
        if interior.contains(&x) {
            let window = &row[x - RADIUS..=x + RADIUS];
            for (&w, &v) in kernel.iter().zip(window) {
                acc += w * v;
            }
        } else {
            for (k, &w) in kernel.iter().enumerate() {
                let src = x as isize + k as isize - RADIUS as isize;
                if src >= 0 && (src as usize) < width {
                    acc += w * row[src as usize];
                }
            }
        }
        *o = acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Direct 2D zero-padded convolution with the outer-product window.
    fn blur_direct(plane: &[f64], width: usize, height: usize) -> Vec<f64> {
        let k = ssim_kernel();
        let r = RADIUS as isize;
        let mut out = vec![0.0; width * height];
        for y in 0..height as isize {
            for x in 0..width as isize {
                let mut acc = 0.0;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let (sx, sy) = (x + dx, y + dy);
                        if sx >= 0 && sy >= 0 && sx < width as isize && sy < height as isize {
                            acc += k[(dx + r) as usize]
                                * k[(dy + r) as usize]
                                * plane[sy as usize * width + sx as usize];
                        }
                    }
                }
                out[y as usize * width + x as usize] = acc;
            }
        }
        out
    }

    #[test]
    fn kernel_is_normalised_symmetric_and_matches_the_gaussian() {
        let k = ssim_kernel();
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for i in 0..SSIM_WINDOW {
            assert_eq!(k[i], k[SSIM_WINDOW - 1 - i]);
        }
        // Ratio of neighbouring taps is exp(-(2d+1)/(2σ²)).
        assert!((k[6] / k[5] - (-1.0f64 / 4.5).exp()).abs() < 1e-14);
        // Centre tap value (normalised), computed by hand: 1 / Σ exp(-d²/4.5), d = -5..5.
        assert!((k[5] - 0.266_011_724_861_794).abs() < 1e-14, "{}", k[5]);
    }

    #[test]
    fn separable_blur_equals_direct_zero_padded_convolution() {
        // Sizes smaller than, equal to and larger than the window.
        for (w, h) in [(3, 4), (11, 11), (17, 9), (1, 13)] {
            let plane: Vec<f64> = (0..w * h).map(|i| ((i * 37 % 11) as f64) / 10.0).collect();
            let fast = blur(&plane, w, h, &kernel_in::<f64>());
            let direct = blur_direct(&plane, w, h);
            for (a, b) in fast.iter().zip(&direct) {
                assert!((a - b).abs() < 1e-13, "{w}x{h}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn blur_of_constant_dims_at_the_border_by_zero_padding() {
        let (w, h) = (20, 20);
        let out = blur(&vec![1.0f64; w * h], w, h, &kernel_in::<f64>());
        // Centre: full window inside the image.
        assert!((out[10 * w + 10] - 1.0).abs() < 1e-12);
        // Corner: only the quarter (plus the centre row/column) of the window is inside.
        let k = ssim_kernel();
        let half: f64 = k[RADIUS..].iter().sum();
        assert!((out[0] - half * half).abs() < 1e-12);
    }
}
