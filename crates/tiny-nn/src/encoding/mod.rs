//! Input encoders: fixed sinusoidal features, and learnable tri-plane, B-spline and hash-grid
//! features.

pub mod bspline;
pub mod hashgrid;
pub mod sinusoidal;
pub mod triplane;

/// Rows per parallel task in the encoders.
pub(crate) const ENC_ROWS: usize = 1024;

/// Lanes of [`dot`]: one AVX register of f32.
const DOT_LANES: usize = 8;

/// `Σ a[i] · b[i]` over the common length, summed in [`DOT_LANES`] interleaved partial sums (lane
/// `j` takes the elements `i ≡ j mod 8`) that are then added pairwise, and a tail added last. A
/// single running sum would be one serial chain of dependent adds that the compiler may not
/// reorder; this fixed reassociation vectorises, and is the same for every call.
#[inline(always)]
pub(crate) fn dot(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut lanes = [0f32; DOT_LANES];
    let (ab, at) = a.split_at(n - n % DOT_LANES);
    let (bb, bt) = b.split_at(n - n % DOT_LANES);
    for (x, y) in ab.chunks_exact(DOT_LANES).zip(bb.chunks_exact(DOT_LANES)) {
        for j in 0..DOT_LANES {
            lanes[j] += x[j] * y[j];
        }
    }
    let [l0, l1, l2, l3, l4, l5, l6, l7] = lanes;
    let mut s = ((l0 + l4) + (l2 + l6)) + ((l1 + l5) + (l3 + l7));
    for (x, y) in at.iter().zip(bt) {
        s += x * y;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::dot;

    #[test]
    fn dot_matches_an_f64_sum_for_every_length() {
        for n in 0..40 {
            let a: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
            let b: Vec<f32> = (0..n).map(|i| (i as f32 * 1.13).cos() - 0.2).collect();
            let exact: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * *y as f64).sum();
            let got = dot(&a, &b) as f64;
            assert!(
                (got - exact).abs() <= 1e-5 * (1.0 + exact.abs()),
                "n = {n}: {got} vs {exact}"
            );
        }
        assert_eq!(dot(&[1.0, 2.0, 3.0], &[4.0, 5.0]), 14.0);
    }
}
