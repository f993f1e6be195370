//! SSIM as 3DGS computes it, with the analytic backward pass the training loss needs.
//!
//! Per channel, with `G` the zero-padded 11×11 Gaussian blur:
//! `μx = G x`, `μy = G y`, `σx² = G x² − μx²`, `σy² = G y² − μy²`, `σxy = G xy − μx μy`,
//! `S = (2 μx μy + C1)(2 σxy + C2) / ((μx² + μy² + C1)(σx² + σy² + C2))`, and SSIM is the mean of
//! `S` over all pixels and channels.
//!
//! Backward (for `∂ mean S / ∂x`): with `A1 = 2μxμy + C1`, `A2 = 2σxy + C2`, `B1 = μx² + μy² + C1`,
//! `B2 = σx² + σy² + C2`, the per-pixel sensitivities to the blurred quantities are
//! `∂S/∂μx = 2μy (A2 − A1) / (B1 B2) − 2μx S (1/B1 − 1/B2)` (through σx² and σxy too),
//! `∂S/∂(G x²) = −S / B2`, `∂S/∂(G xy) = 2 A1 / (B1 B2)`; blurring them back (the blur is
//! self-adjoint) gives `∂/∂x = G(∂μx) + 2x G(∂Gx²) + y G(∂Gxy)`.

use rayon::prelude::*;

use crate::gaussian_blur::{blur, kernel_in};
use crate::{ImageSize, MetricsError, Real, check_image};

/// Stabiliser of the luminance term, `0.01²`.
pub const SSIM_C1: f64 = 0.01 * 0.01;
/// Stabiliser of the contrast-structure term, `0.03²`.
pub const SSIM_C2: f64 = 0.03 * 0.03;

/// Pixels per parallel partial sum. Partial sums over fixed ranges, added in order, give the
/// same bits for any thread count (rayon's `sum` adds in a tree shaped by its splitting).
pub(crate) const SUM_CHUNK: usize = 4096;

/// Mean SSIM of two images over all pixels and the three channels (3DGS definition, zero
/// padding at the borders).
pub fn ssim<T: Real>(size: ImageSize, a: &[[T; 3]], b: &[[T; 3]]) -> Result<f64, MetricsError> {
    check_image(size, a, "a")?;
    check_image(size, b, "b")?;
    let (sum, _) = ssim_sum_and_grad(size, a, b, None);
    Ok(sum / (3 * size.pixels()) as f64)
}

/// Split an interleaved RGB image into three planes.
pub(crate) fn planes<T: Real>(image: &[[T; 3]]) -> [Vec<T>; 3] {
    std::array::from_fn(|c| image.iter().map(|p| p[c]).collect())
}

/// Sum of the SSIM map over all pixels and channels and, when `grad_scale` is given, the
/// gradient of `grad_scale · sum` with respect to `x` (interleaved RGB).
pub(crate) fn ssim_sum_and_grad<T: Real>(
    size: ImageSize,
    x: &[[T; 3]],
    y: &[[T; 3]],
    grad_scale: Option<T>,
) -> (f64, Option<Vec<[T; 3]>>) {
    let xp = planes(x);
    let yp = planes(y);
    let per_channel: Vec<(f64, Option<Vec<T>>)> = (0..3)
        .into_par_iter()
        .map(|c| channel(size, &xp[c], &yp[c], grad_scale))
        .collect();
    let sum = per_channel.iter().map(|(s, _)| s).sum();
    let grad = grad_scale.map(|_| {
        let mut g = vec![[T::default(); 3]; size.pixels()];
        for (c, (_, gc)) in per_channel.iter().enumerate() {
            if let Some(gc) = gc {
                for (p, &v) in g.iter_mut().zip(gc) {
                    p[c] = v;
                }
            }
        }
        g
    });
    (sum, grad)
}

/// One channel: the sum of its SSIM map and, optionally, `scale ·` its gradient.
fn channel<T: Real>(
    size: ImageSize,
    x: &[T],
    y: &[T],
    grad_scale: Option<T>,
) -> (f64, Option<Vec<T>>) {
    let (w, h) = (size.width, size.height);
    let k = kernel_in::<T>();
    let xx: Vec<T> = x.iter().map(|&v| v * v).collect();
    let yy: Vec<T> = y.iter().map(|&v| v * v).collect();
    let xy: Vec<T> = x.iter().zip(y).map(|(&a, &b)| a * b).collect();
    let [mu_x, mu_y, e_xx, e_yy, e_xy] =
        [x, y, &xx[..], &yy[..], &xy[..]].map(|p| blur(p, w, h, &k));
    drop((xx, yy, xy));

    let c1 = T::from_f64(SSIM_C1);
    let c2 = T::from_f64(SSIM_C2);
    let two = T::from_f64(2.0);
    let one = T::from_f64(1.0);

    let Some(scale) = grad_scale else {
        let n = w * h;
        let partial: Vec<f64> = (0..n.div_ceil(SUM_CHUNK))
            .into_par_iter()
            .map(|c| {
                (c * SUM_CHUNK..((c + 1) * SUM_CHUNK).min(n))
                    .map(|i| {
                        let (mx, my) = (mu_x[i], mu_y[i]);
                        let a1 = two * mx * my + c1;
                        let a2 = two * (e_xy[i] - mx * my) + c2;
                        let b1 = mx * mx + my * my + c1;
                        let b2 = (e_xx[i] - mx * mx) + (e_yy[i] - my * my) + c2;
                        (a1 * a2 / (b1 * b2)).to_f64()
                    })
                    .sum::<f64>()
            })
            .collect();
        let sum = partial.iter().sum();
        return (sum, None);
    };

    // Per-pixel sensitivities, in place of the blurred quantities they belong to.
    let mut d_mu = mu_x;
    let mut d_exx = e_xx;
    let mut d_exy = e_xy;
    let partial: Vec<f64> = d_mu
        .par_chunks_mut(SUM_CHUNK)
        .zip(d_exx.par_chunks_mut(SUM_CHUNK))
        .zip(d_exy.par_chunks_mut(SUM_CHUNK))
        .zip(mu_y.par_chunks(SUM_CHUNK).zip(e_yy.par_chunks(SUM_CHUNK)))
        .map(|(((d_mu, d_exx), d_exy), (mu_y, e_yy))| {
            let mut sum = 0.0f64;
            for ((mx_slot, exx_slot), (exy_slot, (&my, &eyy))) in d_mu
                .iter_mut()
                .zip(d_exx.iter_mut())
                .zip(d_exy.iter_mut().zip(mu_y.iter().zip(e_yy)))
            {
                let mx = *mx_slot;
                let a1 = two * mx * my + c1;
                let a2 = two * (*exy_slot - mx * my) + c2;
                let b1 = mx * mx + my * my + c1;
                let b2 = (*exx_slot - mx * mx) + (eyy - my * my) + c2;
                let inv = one / (b1 * b2);
                let s = a1 * a2 * inv;
                *mx_slot =
                    scale * (two * my * (a2 - a1) * inv - two * mx * s * (one / b1 - one / b2));
                *exx_slot = scale * (-s / b2);
                *exy_slot = scale * (two * a1 * inv);
                sum += s.to_f64();
            }
            sum
        })
        .collect();
    let sum: f64 = partial.iter().sum();
    let g_mu = blur(&d_mu, w, h, &k);
    drop(d_mu);
    let g_xx = blur(&d_exx, w, h, &k);
    drop(d_exx);
    let g_xy = blur(&d_exy, w, h, &k);
    drop(d_exy);
    let grad = (0..w * h)
        .into_par_iter()
        .map(|i| g_mu[i] + two * x[i] * g_xx[i] + y[i] * g_xy[i])
        .collect();
    (sum, Some(grad))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(n: usize, f: impl Fn(usize, usize) -> f64) -> Vec<[f64; 3]> {
        (0..n).map(|i| std::array::from_fn(|c| f(i, c))).collect()
    }

    #[test]
    fn identical_images_have_ssim_one() {
        let size = ImageSize::new(13, 7);
        let a = img(91, |i, c| ((i * 7 + c * 3) % 10) as f64 / 10.0);
        assert!((ssim(size, &a, &a).unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn constant_images_match_the_hand_formula() {
        // Two constant images p and q: σ terms vanish wherever the window lies inside the image,
        // but zero padding makes μ = p·w at the border; on a 1x1 image the window weight is the
        // centre tap squared, w = k5².
        let size = ImageSize::new(1, 1);
        let (p, q) = (0.8, 0.3);
        let w = crate::ssim_kernel()[5].powi(2);
        let (mx, my) = (w * p, w * q);
        let (sxx, syy, sxy) = (
            w * p * p - mx * mx,
            w * q * q - my * my,
            w * p * q - mx * my,
        );
        let expected = (2.0 * mx * my + SSIM_C1) * (2.0 * sxy + SSIM_C2)
            / ((mx * mx + my * my + SSIM_C1) * (sxx + syy + SSIM_C2));
        let got = ssim(size, &[[p; 3]], &[[q; 3]]).unwrap();
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
        assert!(got < 0.9);
    }

    #[test]
    fn ssim_is_symmetric_and_drops_with_noise() {
        let size = ImageSize::new(16, 16);
        let a = img(256, |i, c| {
            ((i % 16) as f64 / 16.0 + c as f64 * 0.1).min(1.0)
        });
        let b = img(256, |i, c| {
            (a[i][c] + if (i * 31 + c) % 3 == 0 { 0.2 } else { -0.1 }).clamp(0.0, 1.0)
        });
        let ab = ssim(size, &a, &b).unwrap();
        let ba = ssim(size, &b, &a).unwrap();
        assert!((ab - ba).abs() < 1e-12);
        assert!(ab < 0.95 && ab > -1.0, "{ab}");
    }

    #[test]
    fn bad_inputs_are_errors_naming_the_argument() {
        let size = ImageSize::new(2, 2);
        let a = vec![[0.0f32; 3]; 4];
        let short = vec![[0.0f32; 3]; 3];
        let err = ssim(size, &a, &short).unwrap_err();
        assert_eq!(err.to_string(), "image `b` has 3 pixels, expected 4");
        let mut nan = a.clone();
        nan[2][1] = f32::NAN;
        let err = ssim(size, &nan, &a).unwrap_err();
        assert_eq!(
            err.to_string(),
            "image `a` has a non-finite value at pixel 2"
        );
        let err = ssim(ImageSize::new(0, 4), &[], &[] as &[[f32; 3]]).unwrap_err();
        assert!(matches!(err, MetricsError::EmptyImage { .. }));
    }
}
