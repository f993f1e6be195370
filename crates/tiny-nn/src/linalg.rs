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

/// An operand of a product as it lies in its slice: element (row, col) of the matrix the
/// product reads is at `row * row_stride + col * col_stride`.
#[derive(Clone, Copy)]
struct Layout {
    row_stride: usize,
    col_stride: usize,
}

impl Layout {
    /// Row-major storage of the matrix itself, `cols` wide.
    fn rows_of(cols: usize) -> Self {
        Self {
            row_stride: cols,
            col_stride: 1,
        }
    }

    /// Row-major storage of the transpose, the matrix being `rows` tall.
    fn transposed(rows: usize) -> Self {
        Self {
            row_stride: 1,
            col_stride: rows,
        }
    }

    /// One past the largest index a `rows × cols` matrix (both non-zero) reads.
    fn extent(self, rows: usize, cols: usize) -> usize {
        (rows - 1) * self.row_stride + (cols - 1) * self.col_stride + 1
    }
}

/// `c (m×n, row-major) = a (m×k) · b (k×n)`, or `c += …` when `accumulate`, with `a` and `b`
/// read through their layouts.
///
/// # Panics
/// Panics when a slice is shorter than its shape and layout say (a programming error inside
/// this crate).
#[allow(clippy::too_many_arguments)]
fn product(
    c: &mut [f32],
    a: &[f32],
    a_layout: Layout,
    b: &[f32],
    b_layout: Layout,
    (m, k, n): (usize, usize, usize),
    accumulate: bool,
    par: Parallelism,
) {
    assert!(c.len() >= m * n);
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if !accumulate {
            c[..m * n].fill(0.0);
        }
        return;
    }
    assert!(a.len() >= a_layout.extent(m, k) && b.len() >= b_layout.extent(k, n));
    // SAFETY: m, k, n are non-zero here, and the asserts above prove that every index the strides
    // reach is in bounds: c is m rows of n (row stride n, column stride 1, largest index
    // m·n − 1 < c.len()); a's element (i, p), i < m, p < k, is at i·row_stride + p·col_stride
    // < a_layout.extent(m, k) <= a.len(), and likewise b's (p, j) within b_layout.extent(k, n).
    // The destination does not alias the inputs (distinct `&mut` and `&` borrows).
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
            a_layout.col_stride as isize,
            a_layout.row_stride as isize,
            b.as_ptr(),
            b_layout.col_stride as isize,
            b_layout.row_stride as isize,
            1.0,
            1.0,
            false,
            false,
            false,
            par,
        );
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
    let (la, lb) = (Layout::rows_of(k), Layout::rows_of(n));
    product(c, a, la, b, lb, (m, k, n), accumulate, par);
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
    let (la, lb) = (Layout::rows_of(k), Layout::transposed(k));
    product(c, a, la, b, lb, (m, k, n), accumulate, par);
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
    let (la, lb) = (Layout::transposed(m), Layout::rows_of(n));
    product(c, a, la, b, lb, (m, k, n), accumulate, par);
}
