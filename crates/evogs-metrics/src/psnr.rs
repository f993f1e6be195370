//! Mean squared error and PSNR over RGB in `[0, 1]`.

use crate::{ImageSize, MetricsError, Real, check_image};

/// Mean squared error over all pixels and channels.
pub fn mse<T: Real>(size: ImageSize, a: &[[T; 3]], b: &[[T; 3]]) -> Result<f64, MetricsError> {
    check_image(size, a, "a")?;
    check_image(size, b, "b")?;
    let sum: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c].to_f64() - q[c].to_f64()).powi(2)))
        .sum();
    Ok(sum / (3 * size.pixels()) as f64)
}

/// PSNR in dB for a peak of 1: `−10·log10(MSE)`, as 3DGS's `20·log10(1/sqrt(mse))`. Identical
/// images give `f64::INFINITY`.
pub fn psnr<T: Real>(size: ImageSize, a: &[[T; 3]], b: &[[T; 3]]) -> Result<f64, MetricsError> {
    Ok(psnr_from_mse(mse(size, a, b)?))
}

/// PSNR in dB of a mean squared error, for a peak of 1 (`f64::INFINITY` for 0).
pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_of_a_uniform_error_is_hand_computed() {
        let size = ImageSize::new(3, 2);
        let a = vec![[0.5f32; 3]; 6];
        let b = vec![[0.6f32; 3]; 6];
        // MSE = 0.01 → 20 dB.
        assert!((mse(size, &a, &b).unwrap() - 0.01).abs() < 1e-7);
        assert!((psnr(size, &a, &b).unwrap() - 20.0).abs() < 1e-4);
        // One channel of one pixel off by 1: MSE = 1/18.
        let mut c = a.clone();
        c[4][2] = 1.5;
        assert!((psnr(size, &a, &c).unwrap() - 10.0 * 18f64.log10()).abs() < 1e-9);
        assert_eq!(psnr(size, &a, &a).unwrap(), f64::INFINITY);
    }

    #[test]
    fn mismatched_sizes_are_errors() {
        let size = ImageSize::new(2, 2);
        let err = psnr(size, &[[0.0f32; 3]; 4], &[[0.0f32; 3]; 5]).unwrap_err();
        assert_eq!(err.to_string(), "image `b` has 5 pixels, expected 4");
    }
}
