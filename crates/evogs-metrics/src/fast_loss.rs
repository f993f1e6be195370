//! The training loss of [`photometric_loss`](crate::photometric_loss), fast and allocation-free:
//! the same `0.8·L1 + 0.2·(1 − SSIM)` (DESIGN §7.1) and its gradient with respect to the rendering,
//! plus the MSE for the training PSNR, in two passes over the rows with reused buffers.
//!
//! How: images stay interleaved RGB as the rasterizer writes them. A row of `W` pixels is a row of
//! `3W` numbers whose horizontal neighbours are 3 apart, so every step is an elementwise loop over
//! a row, which the compiler vectorises. Per output row, the separable window is applied
//! vertically first (the up to 11 source rows, zero outside the image) into a row padded with
//! zeros, then horizontally (taps paired by symmetry); the vertical-then-horizontal order gives
//! the same zero-padded convolution as the plain code's horizontal-then-vertical one, up to
//! rounding. Both directions run over chunks of [`CHUNK`] numbers whose sums stay in registers
//! across the taps: the vertical window of all five moments reads each source row of `x` and
//! `y` once per chunk (`k·x` then `x·(k·x)` for `x²`), where blurring one map at a time read the
//! sources five times and stored the partial sums after every tap.
//! Pass 1 blurs `x, y, x², y², xy`, evaluates the SSIM map, its three per-pixel
//! sensitivities (`∂S/∂μx`, `∂S/∂E[x²]`, `∂S/∂E[xy]`, as in [`ssim`](crate::ssim)'s module docs)
//! and the row sums of `S`, `|x − y|` and `(x − y)²`. Pass 2 blurs the sensitivities back (the
//! window is self-adjoint) and adds the L1 sign term.
//!
//! Determinism: rows are independent and run in parallel in blocks of fixed size; a row's sums
//! are taken over eight fixed lanes, and rows are added in row order, so the result is
//! bit-identical for any number of threads. On x86-64 with AVX2 and FMA (checked at run time)
//! the same code is compiled with both enabled: every step is the same IEEE operation per
//! element, and each multiply-add is fused in every build ([`Real::mul_add`]: an instruction
//! there, a correctly rounded library call in the baseline build), so both give the same bits.
//!
//! What it is not: the reference. [`photometric_loss`](crate::photometric_loss) is; the tests
//! check this one against it and against f64 finite differences.

use rayon::prelude::*;

use crate::gaussian_blur::{SSIM_WINDOW, kernel_in};
use crate::loss::{L1_WEIGHT, SSIM_WEIGHT};
use crate::ssim::{SSIM_C1, SSIM_C2};
use crate::{ImageSize, MetricsError, Real, check_image};

/// Taps on each side of the window centre.
const RADIUS: usize = SSIM_WINDOW / 2;
/// Zeros on each side of a padded row: `RADIUS` pixels of three channels.
const PAD: usize = 3 * RADIUS;
/// Output rows per parallel task (does not change any result).
const BLOCK_ROWS: usize = 8;
/// Lanes of the per-row sums.
const LANES: usize = 8;
/// Numbers per chunk of a row whose window sums are kept in registers (two AVX2 vectors of
/// f32); a row's last `3W mod CHUNK` numbers go one at a time through the same operations.
const CHUNK: usize = 16;

/// The loss of one rendering and its terms, from [`LossWorkspace::compute`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LossValues {
    /// `0.8·l1 + 0.2·(1 − ssim)`.
    pub loss: f64,
    /// Mean absolute error over all pixels and channels.
    pub l1: f64,
    /// Mean SSIM (3DGS definition).
    pub ssim: f64,
    /// Mean squared error over all pixels and channels (for the training PSNR).
    pub mse: f64,
}

/// Buffers of the fast loss, reused from call to call: after the first call at an image size,
/// [`compute`](Self::compute) allocates nothing.
#[derive(Debug, Default)]
pub struct LossWorkspace<T> {
    /// `∂loss/∂rendered`, interleaved RGB, of the last call.
    gradient: Vec<[T; 3]>,
    /// Pass 1 → pass 2: the scaled sensitivities to `μx`, `E[x²]` and `E[xy]`, interleaved.
    d_mu: Vec<T>,
    d_xx: Vec<T>,
    d_xy: Vec<T>,
    /// One scratch area per block of rows.
    scratch: Vec<T>,
    /// Per row: sums of `S`, `|x − y|`, `(x − y)²`.
    row_sums: Vec<[f64; 3]>,
}

/// Length of a block's scratch for rows of `n` numbers: five padded rows and eight plain ones.
fn scratch_len(n: usize) -> usize {
    5 * (n + 2 * PAD) + 8 * n
}

impl<T: Real> LossWorkspace<T> {
    /// An empty workspace; the first call sizes it.
    pub fn new() -> Self {
        Self {
            gradient: Vec::new(),
            d_mu: Vec::new(),
            d_xx: Vec::new(),
            d_xy: Vec::new(),
            scratch: Vec::new(),
            row_sums: Vec::new(),
        }
    }

    /// The gradient `∂loss/∂rendered` of the last [`compute`](Self::compute), interleaved RGB.
    /// The L1 part uses `sign(0) = 0`, as the plain loss does.
    pub fn gradient(&self) -> &[[T; 3]] {
        &self.gradient
    }

    /// Computes the loss of `rendered` against `gt` and keeps its gradient (see
    /// [`gradient`](Self::gradient)).
    ///
    /// # Errors
    /// An empty size, an image with the wrong number of pixels, or a non-finite value (naming
    /// the image and the pixel), as [`photometric_loss`](crate::photometric_loss).
    pub fn compute(
        &mut self,
        size: ImageSize,
        rendered: &[[T; 3]],
        gt: &[[T; 3]],
    ) -> Result<LossValues, MetricsError> {
        self.compute_with(size, rendered, gt, avx2_available())
    }

    /// [`compute`](Self::compute) with the AVX2 build used only where `avx2` (and the CPU has it).
    pub(crate) fn compute_with(
        &mut self,
        size: ImageSize,
        rendered: &[[T; 3]],
        gt: &[[T; 3]],
        avx2: bool,
    ) -> Result<LossValues, MetricsError> {
        check_sizes(size, rendered, "rendered")?;
        check_sizes(size, gt, "gt")?;
        let avx2 = avx2 && avx2_available();
        let (w, h) = (size.width, size.height);
        let n = 3 * w;
        self.gradient.resize(w * h, [T::default(); 3]);
        for map in [&mut self.d_mu, &mut self.d_xx, &mut self.d_xy] {
            map.resize(n * h, T::default());
        }
        let blocks = h.div_ceil(BLOCK_ROWS);
        let sl = scratch_len(n);
        if self.scratch.len() != blocks * sl {
            // Padding must start at zero; only the interior of padded rows is ever written.
            self.scratch.clear();
            self.scratch.resize(blocks * sl, T::default());
        }
        self.row_sums.resize(h, [0.0; 3]);

        let count = (3 * size.pixels()) as f64;
        let ctx = Ctx {
            x: rendered.as_flattened(),
            y: gt.as_flattened(),
            w,
            h,
            k: kernel_in::<T>(),
            ssim_scale: T::from_f64(-SSIM_WEIGHT / count),
            l1_step: T::from_f64(L1_WEIGHT / count),
        };
        let chunk = BLOCK_ROWS * n;
        self.d_mu
            .par_chunks_mut(chunk)
            .zip(self.d_xx.par_chunks_mut(chunk))
            .zip(self.d_xy.par_chunks_mut(chunk))
            .zip(self.scratch.par_chunks_mut(sl))
            .zip(self.row_sums.par_chunks_mut(BLOCK_ROWS))
            .enumerate()
            .for_each(|(b, ((((d_mu, d_xx), d_xy), scratch), sums))| {
                let out = Sensitivities { d_mu, d_xx, d_xy };
                if avx2 {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: `avx2` is true only where `avx2_available()` found AVX2 and FMA on this CPU.
                    unsafe {
                        pass1_avx2(&ctx, b * BLOCK_ROWS, out, scratch, sums);
                    };
                } else {
                    pass1(&ctx, b * BLOCK_ROWS, out, scratch, sums);
                }
            });

        let (mut s_sum, mut l1_sum, mut sq_sum) = (0.0, 0.0, 0.0);
        for [s, l1, sq] in &self.row_sums {
            s_sum += s;
            l1_sum += l1;
            sq_sum += sq;
        }
        if !(s_sum.is_finite() && l1_sum.is_finite()) {
            // A NaN or infinity in either image shows in the sums; name where it is.
            check_image(size, rendered, "rendered")?;
            check_image(size, gt, "gt")?;
        }

        let maps = [&self.d_mu[..], &self.d_xx[..], &self.d_xy[..]];
        self.gradient
            .as_flattened_mut()
            .par_chunks_mut(chunk)
            .zip(self.scratch.par_chunks_mut(sl))
            .enumerate()
            .for_each(|(b, (grad, scratch))| {
                if avx2 {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: `avx2` is true only where `avx2_available()` found AVX2 and FMA on this CPU.
                    unsafe {
                        pass2_avx2(&ctx, b * BLOCK_ROWS, maps, grad, scratch);
                    };
                } else {
                    pass2(&ctx, b * BLOCK_ROWS, maps, grad, scratch);
                }
            });

        let l1 = l1_sum / count;
        let ssim = s_sum / count;
        Ok(LossValues {
            loss: L1_WEIGHT * l1 + SSIM_WEIGHT * (1.0 - ssim),
            l1,
            ssim,
            mse: sq_sum / count,
        })
    }
}

/// Whether the AVX2 build (AVX2 and FMA) can run here.
fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The size checks of [`check_image`] without the scan for non-finite values (the sums find
/// those).
fn check_sizes<T: Real>(
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
    Ok(())
}

/// What both passes read.
struct Ctx<'a, T> {
    /// The rendering, interleaved, `3W` numbers a row.
    x: &'a [T],
    /// The ground truth, interleaved.
    y: &'a [T],
    w: usize,
    h: usize,
    k: [T; SSIM_WINDOW],
    /// `−0.2 / count`: the SSIM term's factor on `∂ Σ S`.
    ssim_scale: T,
    /// `0.8 / count`: the L1 term's gradient where the difference is positive.
    l1_step: T,
}

/// A block's rows of the three sensitivity maps.
struct Sensitivities<'a, T> {
    d_mu: &'a mut [T],
    d_xx: &'a mut [T],
    d_xy: &'a mut [T],
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn pass1_avx2<T: Real>(
    ctx: &Ctx<'_, T>,
    row0: usize,
    out: Sensitivities<'_, T>,
    scratch: &mut [T],
    sums: &mut [[f64; 3]],
) {
    pass1(ctx, row0, out, scratch, sums);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn pass2_avx2<T: Real>(
    ctx: &Ctx<'_, T>,
    row0: usize,
    maps: [&[T]; 3],
    grad: &mut [T],
    scratch: &mut [T],
) {
    pass2(ctx, row0, maps, grad, scratch);
}

/// Pass 1 over the rows `row0..` of one block: blurred moments, the SSIM map, its sensitivities
/// and the row sums.
#[inline(always)]
fn pass1<T: Real>(
    ctx: &Ctx<'_, T>,
    row0: usize,
    out: Sensitivities<'_, T>,
    scratch: &mut [T],
    sums: &mut [[f64; 3]],
) {
    let n = 3 * ctx.w;
    let padded = n + 2 * PAD;
    let (pads, plain) = scratch.split_at_mut(5 * padded);
    let [p_x, p_y, p_xx, p_yy, p_xy] = split5(pads, padded);
    let (blurred, rest) = plain.split_at_mut(5 * n);
    let [mu_x, mu_y, e_xx, e_yy, e_xy] = split5(blurred, n);
    let (s_row, rest) = rest.split_at_mut(n);
    let (abs_row, rest) = rest.split_at_mut(n);
    let sq_row = &mut rest[..n];
    let (c1, c2) = (T::from_f64(SSIM_C1), T::from_f64(SSIM_C2));
    let (one, two) = (T::from_f64(1.0), T::from_f64(2.0));
    let scale = ctx.ssim_scale;

    for (r, sum) in sums.iter_mut().enumerate() {
        let y = row0 + r;
        let at = r * n..(r + 1) * n;
        vertical_moments(
            ctx,
            y,
            &mut [
                &mut p_x[PAD..PAD + n],
                &mut p_y[PAD..PAD + n],
                &mut p_xx[PAD..PAD + n],
                &mut p_yy[PAD..PAD + n],
                &mut p_xy[PAD..PAD + n],
            ],
        );
        horizontal(&ctx.k, p_x, mu_x);
        horizontal(&ctx.k, p_y, mu_y);
        horizontal(&ctx.k, p_xx, e_xx);
        horizontal(&ctx.k, p_yy, e_yy);
        horizontal(&ctx.k, p_xy, e_xy);

        let d_mu = &mut out.d_mu[at.clone()];
        let d_xx = &mut out.d_xx[at.clone()];
        let d_xy = &mut out.d_xy[at];
        for i in 0..n {
            let (mx, my) = (mu_x[i], mu_y[i]);
            let a1 = two * mx * my + c1;
            let a2 = two * (e_xy[i] - mx * my) + c2;
            let b1 = mx * mx + my * my + c1;
            let b2 = (e_xx[i] - mx * mx) + (e_yy[i] - my * my) + c2;
            let inv1 = one / b1;
            let inv2 = one / b2;
            let inv = inv1 * inv2;
            let s = a1 * a2 * inv;
            d_mu[i] = scale * (two * my * (a2 - a1) * inv - two * mx * s * (inv1 - inv2));
            d_xx[i] = scale * (-(s * inv2));
            d_xy[i] = scale * (two * a1 * inv);
            s_row[i] = s;
        }
        let xr = &ctx.x[y * n..(y + 1) * n];
        let yr = &ctx.y[y * n..(y + 1) * n];
        for (((a, s), &p), &q) in abs_row.iter_mut().zip(sq_row.iter_mut()).zip(xr).zip(yr) {
            let d = p - q;
            *a = if d < T::default() { -d } else { d };
            *s = d * d;
        }
        *sum = [lane_sum(s_row), lane_sum(abs_row), lane_sum(sq_row)];
    }
}

/// Pass 2 over the rows `row0..` of one block: the gradient.
#[inline(always)]
fn pass2<T: Real>(
    ctx: &Ctx<'_, T>,
    row0: usize,
    [d_mu, d_xx, d_xy]: [&[T]; 3],
    grad: &mut [T],
    scratch: &mut [T],
) {
    let n = 3 * ctx.w;
    let padded = n + 2 * PAD;
    let (pads, plain) = scratch.split_at_mut(5 * padded);
    let [p_mu, p_xx, p_xy, _, _] = split5(pads, padded);
    let (blurred, _) = plain.split_at_mut(5 * n);
    let [g_mu, g_xx, g_xy, _, _] = split5(blurred, n);
    let zero = T::default();
    let two = T::from_f64(2.0);
    let step = ctx.l1_step;
    let rows = grad.len() / n;
    for r in 0..rows {
        let y = row0 + r;
        vertical_maps(
            ctx,
            y,
            [d_mu, d_xx, d_xy],
            &mut [
                &mut p_mu[PAD..PAD + n],
                &mut p_xx[PAD..PAD + n],
                &mut p_xy[PAD..PAD + n],
            ],
        );
        horizontal(&ctx.k, p_mu, g_mu);
        horizontal(&ctx.k, p_xx, g_xx);
        horizontal(&ctx.k, p_xy, g_xy);
        let xr = &ctx.x[y * n..(y + 1) * n];
        let yr = &ctx.y[y * n..(y + 1) * n];
        let out = &mut grad[r * n..(r + 1) * n];
        for i in 0..n {
            let (p, q) = (xr[i], yr[i]);
            let d = p - q;
            let l1 = if d > zero {
                step
            } else if d < zero {
                -step
            } else {
                zero
            };
            out[i] = g_mu[i] + two * p * g_xx[i] + q * g_xy[i] + l1;
        }
    }
}

/// Five consecutive rows of `len` numbers.
#[inline(always)]
fn split5<T>(buf: &mut [T], len: usize) -> [&mut [T]; 5] {
    let (a, rest) = buf.split_at_mut(len);
    let (b, rest) = rest.split_at_mut(len);
    let (c, rest) = rest.split_at_mut(len);
    let (d, rest) = rest.split_at_mut(len);
    [a, b, c, d, &mut rest[..len]]
}

/// The source rows of output row `y`'s vertical window, `y − 5 ..= y + 5` inside the image.
#[inline(always)]
fn window_rows(y: usize, h: usize) -> std::ops::RangeInclusive<usize> {
    y.saturating_sub(RADIUS)..=(y + RADIUS).min(h - 1)
}

/// The vertical window of output row `y` of the five moments `x, y, x², y², xy` into `out`
/// (rows of `3W` numbers): `Σ_taps k·f` over [`window_rows`] in order, each multiply-add fused.
#[inline(always)]
fn vertical_moments<T: Real>(ctx: &Ctx<'_, T>, y: usize, out: &mut [&mut [T]; 5]) {
    let n = 3 * ctx.w;
    let mut c = 0;
    while c + CHUNK <= n {
        moments_chunk::<T, CHUNK>(ctx, y, c, out);
        c += CHUNK;
    }
    while c < n {
        moments_chunk::<T, 1>(ctx, y, c, out);
        c += 1;
    }
}

/// [`vertical_moments`] of the `L` numbers from `c`.
#[inline(always)]
fn moments_chunk<T: Real, const L: usize>(
    ctx: &Ctx<'_, T>,
    y: usize,
    c: usize,
    out: &mut [&mut [T]; 5],
) {
    let n = 3 * ctx.w;
    let mut acc = [[T::default(); L]; 5];
    for src in window_rows(y, ctx.h) {
        let k = ctx.k[src + RADIUS - y];
        let at = src * n + c;
        let (xs, ys) = (&ctx.x[at..at + L], &ctx.y[at..at + L]);
        for j in 0..L {
            let (p, q) = (xs[j], ys[j]);
            let (kp, kq) = (k * p, k * q);
            acc[0][j] += kp;
            acc[1][j] += kq;
            acc[2][j] = kp.mul_add(p, acc[2][j]);
            acc[3][j] = kq.mul_add(q, acc[3][j]);
            acc[4][j] = kp.mul_add(q, acc[4][j]);
        }
    }
    for (o, a) in out.iter_mut().zip(&acc) {
        o[c..c + L].copy_from_slice(a);
    }
}

/// The vertical window of output row `y` of `M` maps (rows of `3W` numbers) into `out`:
/// `Σ_taps k·map` over [`window_rows`] in order, each multiply-add fused.
#[inline(always)]
fn vertical_maps<T: Real, const M: usize>(
    ctx: &Ctx<'_, T>,
    y: usize,
    maps: [&[T]; M],
    out: &mut [&mut [T]; M],
) {
    let n = 3 * ctx.w;
    let mut c = 0;
    while c + CHUNK <= n {
        maps_chunk::<T, M, CHUNK>(ctx, y, c, &maps, out);
        c += CHUNK;
    }
    while c < n {
        maps_chunk::<T, M, 1>(ctx, y, c, &maps, out);
        c += 1;
    }
}

/// [`vertical_maps`] of the `L` numbers from `c`.
#[inline(always)]
fn maps_chunk<T: Real, const M: usize, const L: usize>(
    ctx: &Ctx<'_, T>,
    y: usize,
    c: usize,
    maps: &[&[T]; M],
    out: &mut [&mut [T]; M],
) {
    let n = 3 * ctx.w;
    let mut acc = [[T::default(); L]; M];
    for src in window_rows(y, ctx.h) {
        let k = ctx.k[src + RADIUS - y];
        let at = src * n + c;
        for (a, map) in acc.iter_mut().zip(maps) {
            let m = &map[at..at + L];
            for j in 0..L {
                a[j] = k.mul_add(m[j], a[j]);
            }
        }
    }
    for (o, a) in out.iter_mut().zip(&acc) {
        o[c..c + L].copy_from_slice(a);
    }
}

/// `out[i] = k5·p[i] + Σ_{d=1..5} k[5−d]·(p[i − 3d] + p[i + 3d])` (each multiply-add fused) on
/// a row padded with `PAD` zeros each side (`padded` is `out.len() + 2·PAD` long).
#[inline(always)]
fn horizontal<T: Real>(k: &[T; SSIM_WINDOW], padded: &[T], out: &mut [T]) {
    let n = out.len();
    let mut c = 0;
    while c + CHUNK <= n {
        horizontal_chunk::<T, CHUNK>(k, padded, out, c);
        c += CHUNK;
    }
    while c < n {
        horizontal_chunk::<T, 1>(k, padded, out, c);
        c += 1;
    }
}

/// [`horizontal`] of the `L` numbers from `c`.
#[inline(always)]
fn horizontal_chunk<T: Real, const L: usize>(
    k: &[T; SSIM_WINDOW],
    padded: &[T],
    out: &mut [T],
    c: usize,
) {
    let centre = &padded[PAD + c..PAD + c + L];
    let mut acc = [T::default(); L];
    for j in 0..L {
        acc[j] = k[RADIUS] * centre[j];
    }
    for d in 1..=RADIUS {
        let kd = k[RADIUS - d];
        let left = &padded[PAD + c - 3 * d..PAD + c - 3 * d + L];
        let right = &padded[PAD + c + 3 * d..PAD + c + 3 * d + L];
        for j in 0..L {
            acc[j] = kd.mul_add(left[j] + right[j], acc[j]);
        }
    }
    out[c..c + L].copy_from_slice(&acc);
}

/// Sum of `v` in f64 over eight fixed lanes (element `i` to lane `i % 8`), the lanes added in
/// a fixed order: the same bits in every build.
#[inline(always)]
fn lane_sum<T: Real>(v: &[T]) -> f64 {
    let mut lanes = [0.0f64; LANES];
    let mut chunks = v.chunks_exact(LANES);
    for c in &mut chunks {
        for (l, &x) in lanes.iter_mut().zip(c) {
            *l += x.to_f64();
        }
    }
    for (l, &x) in lanes.iter_mut().zip(chunks.remainder()) {
        *l += x.to_f64();
    }
    ((lanes[0] + lanes[4]) + (lanes[2] + lanes[6]))
        + ((lanes[1] + lanes[5]) + (lanes[3] + lanes[7]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photometric_loss;

    fn pair(w: usize, h: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let gt: Vec<[f32; 3]> = (0..w * h)
            .map(|i| std::array::from_fn(|c| ((i * 13 + c * 7) % 17) as f32 / 17.0))
            .collect();
        let r = gt
            .iter()
            .enumerate()
            .map(|(i, g)| std::array::from_fn(|c| g[c] + ((i * 7919 + c) % 11) as f32 / 50.0 - 0.1))
            .collect();
        (r, gt)
    }

    fn bits(v: &[[f32; 3]]) -> Vec<u32> {
        v.as_flattened().iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn avx2_and_baseline_builds_give_the_same_bits() {
        for (w, h) in [(37, 23), (1, 1), (400, 17)] {
            let (r, gt) = pair(w, h);
            let size = ImageSize::new(w, h);
            let mut a = LossWorkspace::new();
            let mut b = LossWorkspace::new();
            let va = a.compute_with(size, &r, &gt, true).unwrap();
            let vb = b.compute_with(size, &r, &gt, false).unwrap();
            assert_eq!(va, vb, "{w}x{h}");
            assert_eq!(bits(a.gradient()), bits(b.gradient()), "{w}x{h}");
        }
    }

    #[test]
    fn same_bits_for_any_thread_count_and_on_reuse() {
        let (w, h) = (61, 45);
        let (r, gt) = pair(w, h);
        let size = ImageSize::new(w, h);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut ws = LossWorkspace::new();
                let v = ws.compute(size, &r, &gt).unwrap();
                (v, bits(ws.gradient()))
            })
        };
        let one = run(1);
        assert_eq!(one, run(3));
        // A workspace used first at another size gives the same bits.
        let mut ws = LossWorkspace::new();
        let (r2, gt2) = pair(13, 70);
        ws.compute(ImageSize::new(13, 70), &r2, &gt2).unwrap();
        let v = ws.compute(size, &r, &gt).unwrap();
        assert_eq!((v, bits(ws.gradient())), one);
    }

    #[test]
    fn f64_matches_the_plain_loss() {
        for (w, h) in [(14, 12), (3, 40), (1, 1), (31, 5)] {
            let (r, gt) = pair(w, h);
            let r: Vec<[f64; 3]> = r.iter().map(|p| p.map(f64::from)).collect();
            let gt: Vec<[f64; 3]> = gt.iter().map(|p| p.map(f64::from)).collect();
            let size = ImageSize::new(w, h);
            let plain = photometric_loss(size, &r, &gt).unwrap();
            let mut ws = LossWorkspace::new();
            let fast = ws.compute(size, &r, &gt).unwrap();
            assert!((fast.loss - plain.loss).abs() < 1e-13, "{w}x{h}");
            assert!((fast.ssim - plain.ssim).abs() < 1e-13, "{w}x{h}");
            assert!((fast.l1 - plain.l1).abs() < 1e-14, "{w}x{h}");
            let mse = crate::mse(size, &r, &gt).unwrap();
            assert!((fast.mse - mse).abs() < 1e-14, "{w}x{h}");
            for (a, b) in ws
                .gradient()
                .as_flattened()
                .iter()
                .zip(plain.d_rendered.as_flattened())
            {
                assert!(
                    (a - b).abs() <= 1e-15 + 1e-11 * b.abs(),
                    "{w}x{h}: {a} vs {b}"
                );
            }
        }
    }
}
