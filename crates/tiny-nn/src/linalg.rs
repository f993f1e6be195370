//! Dense f32 matrix products through the `gemm` crate, on row-major slices.
//!
//! All products here accumulate in f32. Networks in f16 storage convert their operands to f32
//! blocks first and call these f32 kernels: `gemm`'s own f16 path (`gemm::f16`) does pack to f32
//! and multiply in f32 inside one k-block, but it rounds the running sum to f16 in the destination
//! between k-blocks and returns an f16 result before the bias is added, so it is not used.

use gemm::{Parallelism, gemm};

/// Threading of one product.
pub fn parallelism(threads: usize) -> Parallelism {
    if threads <= 1 {
        Parallelism::None
    } else {
        Parallelism::Rayon(threads)
    }
}

/// `c (m×n) = a (m×k) · b (k×n)` (or `c += …` when `accumulate`), all row-major.
///
/// # Panics
/// Panics when a slice is shorter than its shape says (a programming error inside this crate).
pub fn matmul(
    c: &mut [f32],
    a: &[f32],
    b: &[f32],
    (m, k, n): (usize, usize, usize),
    accumulate: bool,
    par: Parallelism,
) {
    assert!(c.len() >= m * n && a.len() >= m * k && b.len() >= k * n);
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if !accumulate {
            c[..m * n].fill(0.0);
        }
        return;
    }
    // SAFETY: the asserts above prove that every index the strides reach is in bounds: c holds
    // m rows of n (row stride n, column stride 1), a holds m rows of k, b holds k rows of n. The
    // destination does not alias the inputs (distinct `&mut` and `&` borrows).
    unsafe {
        gemm(
            m,
            n,
            k,
            c.as_mut_ptr(),
            1,
            n as isize,
            accumulate,
            a.as_ptr(),
            1,
            k as isize,
            b.as_ptr(),
            1,
            n as isize,
            1.0,
            1.0,
            false,
            false,
            false,
            par,
        );
    }
}

/// `c (m×n) = a (m×k) · bᵀ` where `b` is stored row-major as n×k.
///
/// # Panics
/// Panics when a slice is shorter than its shape says.
pub fn matmul_a_bt(
    c: &mut [f32],
    a: &[f32],
    b: &[f32],
    (m, k, n): (usize, usize, usize),
    accumulate: bool,
    par: Parallelism,
) {
    assert!(c.len() >= m * n && a.len() >= m * k && b.len() >= k * n);
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if !accumulate {
            c[..m * n].fill(0.0);
        }
        return;
    }
    // SAFETY: as in `matmul`; bᵀ element (p, j) is b[j * k + p]: row stride 1, column stride k,
    // and j < n, p < k keep it inside b's n·k values.
    unsafe {
        gemm(
            m,
            n,
            k,
            c.as_mut_ptr(),
            1,
            n as isize,
            accumulate,
            a.as_ptr(),
            1,
            k as isize,
            b.as_ptr(),
            k as isize,
            1,
            1.0,
            1.0,
            false,
            false,
            false,
            par,
        );
    }
}

/// `c (m×n) = aᵀ · b` where `a` is stored row-major as k×m and `b` as k×n.
///
/// # Panics
/// Panics when a slice is shorter than its shape says.
pub fn matmul_at_b(
    c: &mut [f32],
    a: &[f32],
    b: &[f32],
    (m, k, n): (usize, usize, usize),
    accumulate: bool,
    par: Parallelism,
) {
    assert!(c.len() >= m * n && a.len() >= m * k && b.len() >= k * n);
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if !accumulate {
            c[..m * n].fill(0.0);
        }
        return;
    }
    // SAFETY: as in `matmul`; aᵀ element (i, p) is a[p * m + i]: row stride 1, column stride m,
    // and i < m, p < k keep it inside a's k·m values.
    unsafe {
        gemm(
            m,
            n,
            k,
            c.as_mut_ptr(),
            1,
            n as isize,
            accumulate,
            a.as_ptr(),
            m as isize,
            1,
            b.as_ptr(),
            1,
            n as isize,
            1.0,
            1.0,
            false,
            false,
            false,
            par,
        );
    }
}
