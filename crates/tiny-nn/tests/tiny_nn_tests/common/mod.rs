//! Helpers shared by the integration tests.
#![allow(dead_code)]

/// Deterministic pseudo-random values in [-s, s] (a tiny LCG; tests only need variety).
pub fn vals(n: usize, seed: u64, s: f32) -> Vec<f32> {
    let mut x = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * s
        })
        .collect()
}

/// `Σ c·y` in f64.
pub fn dot(y: &[f32], c: &[f32]) -> f64 {
    y.iter().zip(c).map(|(&a, &b)| a as f64 * b as f64).sum()
}

/// Central finite differences of `f` at `x` (f32 evaluation, step `h`), compared with `grad`:
/// asserts `|g - fd| <= tol · (1 + |fd|)` for every coordinate.
pub fn check_fd(
    what: &str,
    x: &[f32],
    grad: &[f32],
    h: f32,
    tol: f64,
    mut f: impl FnMut(&[f32]) -> f64,
) {
    assert_eq!(x.len(), grad.len(), "{what}: gradient length");
    let mut xx = x.to_vec();
    for i in 0..x.len() {
        xx[i] = x[i] + h;
        let lp = f(&xx);
        xx[i] = x[i] - h;
        let lm = f(&xx);
        xx[i] = x[i];
        let fd = (lp - lm) / (2.0 * h as f64);
        let g = grad[i] as f64;
        assert!(
            (g - fd).abs() <= tol * (1.0 + fd.abs()),
            "{what} {i}: analytic {g} vs finite difference {fd}"
        );
    }
}
