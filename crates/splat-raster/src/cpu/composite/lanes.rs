//! The fast compositing kernels: the same per-pixel arithmetic as [`super::scalar`], eight pixels
//! of a tile row at a time (the lanes of a [`Simd`] build), with the vectorised
//! [`exp`](super::super::simd::exp).
//!
//! A tile is 32 blocks of 8 pixels (row `y`, half `h`), stored in lane order, so block `2y + h`
//! holds lanes `16y + 8h .. 16y + 8h + 8`. For each list entry, the blocks that meet its bounding
//! box are visited; in each, `σ` is computed for the eight pixels exactly as the reference does
//! and the exact ellipse test `σ <= sigma_cut` (with the bounding box and the pixels still
//! running) masks the lanes; a block with no lane left is skipped before the `exp`. Lanes are
//! updated by selects, so a lane that is masked off keeps its state bit for bit.
//!
//! With the same `exp`, the forward kernel gives the reference kernel's outputs bit for bit (the
//! same operations in the same order per pixel). The backward kernel computes the reference's
//! gradients with its terms regrouped (see [`backward_tile_into`]) and sums each entry's gradient
//! over the pixels per lane, then across the lanes in a fixed order, so its sums differ from the
//! reference's by rounding only, and never depend on the thread count.

use super::super::project::{Splat, SplatGrads};
use super::super::simd::{ExpConsts, Kernel, Simd, W, exp_in_range};
use super::{LANES, TileOut, TileRect};
use crate::constants::{ALPHA_MAX, ALPHA_MIN, T_MIN, TILE};
use crate::frame::Frame;
use crate::output::Counters;
use crate::output::PixelGrads;

/// Blocks of [`W`] pixels per tile.
const BLOCKS: usize = LANES / W;
/// Blocks per tile row.
const HALVES: usize = TILE as usize / W;

/// The per-entry quantities of a block column `h` that do not depend on the row.
#[derive(Clone, Copy)]
struct Column<V: Simd> {
    /// Lanes inside the entry's bounding box.
    inside: V::M,
    /// `dx = pixel centre x − u`.
    dx: V::F,
    /// `a·dx·dx`, as the reference computes it.
    adx2: V::F,
    /// `b·dx`.
    bdx: V::F,
}

/// The pixel centres `x + 0.5` of each block column of tile `rect`.
#[inline(always)]
fn pixel_columns<V: Simd>(v: V, rect: &TileRect) -> [V::F; HALVES] {
    std::array::from_fn(|h| {
        v.lanes(std::array::from_fn(|l| {
            (rect.x0 + (h * W) as u32 + l as u32) as f32 + 0.5
        }))
    })
}

/// The columns of tile `rect` (pixel centres `px`, from [`pixel_columns`]) met by the clipped
/// bounding box `[x0, x1]` of splat `s`.
#[inline(always)]
fn columns<V: Simd>(
    v: V,
    rect: &TileRect,
    px: &[V::F; HALVES],
    s: &Splat,
    x0: u32,
    x1: u32,
) -> (usize, usize, [Column<V>; HALVES]) {
    let (lx0, lx1) = (x0 - rect.x0, x1 - rect.x0);
    let (h0, h1) = (lx0 as usize / W, lx1 as usize / W);
    let zero = v.splat(0.0);
    let mut cols = [Column {
        inside: v.none(),
        dx: zero,
        adx2: zero,
        bdx: zero,
    }; HALVES];
    let (u, a, b) = (v.splat(s.u), v.splat(s.a), v.splat(s.b));
    for (h, col) in cols.iter_mut().enumerate().take(h1 + 1).skip(h0) {
        let first = (h * W) as u32;
        let lo = lx0.saturating_sub(first);
        let hi = (lx1 - first).min(W as u32 - 1);
        let dx = px[h] - u;
        *col = Column {
            inside: v.range(lo, hi),
            dx,
            adx2: a * dx * dx,
            bdx: b * dx,
        };
    }
    (h0, h1, cols)
}

/// `σ = 0.5 (a dx² + c dy²) + b dx dy` on one block of row `dy` (`cdy2 = c·dy·dy`), in the
/// reference's order of operations.
#[inline(always)]
fn sigma<V: Simd>(v: V, col: &Column<V>, cdy2: f32, dy: f32) -> V::F {
    (col.adx2 + v.splat(cdy2)) * v.splat(0.5) + col.bdx * v.splat(dy)
}

/// [`forward_tile_into`] as a [`Kernel`], to be compiled for the CPU's instruction set.
pub(crate) struct Forward<'a> {
    pub frame: &'a Frame,
    pub tile: usize,
    pub ids: &'a [u32],
    pub splats: &'a [Splat],
    pub background: [f32; 3],
    pub out: TileOut<'a>,
}

impl Kernel for Forward<'_> {
    type Output = Counters;

    #[inline(always)]
    fn run<V: Simd>(self, v: V) -> Counters {
        forward_tile_into(
            v,
            self.frame,
            self.tile,
            self.ids,
            self.splats,
            self.background,
            self.out,
        )
    }
}

/// The per-pixel state of a tile being composited, one vector per block.
struct Blend<V: Simd> {
    /// Transmittance.
    t: [V::F; BLOCKS],
    /// Lanes that stopped (`T` would fall below [`T_MIN`]).
    done: [V::M; BLOCKS],
    red: [V::F; BLOCKS],
    green: [V::F; BLOCKS],
    blue: [V::F; BLOCKS],
    depth: [V::F; BLOCKS],
    /// One past the list position of the last entry blended.
    last: [V::I; BLOCKS],
    /// The number of entries blended.
    blended: [V::I; BLOCKS],
    /// Pixels still running.
    active: usize,
}

/// One list entry's constants as vectors.
struct Entry<V: Simd> {
    opacity: V::F,
    rgb: [V::F; 3],
    z: V::F,
    /// One past its list position.
    pos: V::I,
}

/// The kernel's constants as vectors.
struct Consts<V: Simd> {
    exp: ExpConsts<V>,
    zero: V::F,
    one: V::F,
    alpha_max: V::F,
    alpha_min: V::F,
    t_min: V::F,
}

/// Blends entry `e` into the `N` distinct blocks `b` (with `σ` and the lanes the ellipse test
/// keeps), in lockstep: each block's operations are the reference's, and the blocks' chains of
/// dependent operations (the `exp` above all) are independent, so the core overlaps them.
#[inline(always)]
fn blend_blocks<V: Simd, const N: usize>(
    v: V,
    k: &Consts<V>,
    e: &Entry<V>,
    st: &mut Blend<V>,
    b: [usize; N],
    sig: [V::F; N],
    near: [V::M; N],
) {
    // Plain loops, not `std::array::from_fn`: its closures are not always inlined into the
    // caller compiled for the CPU's instruction set, and out of line each lane operation
    // becomes a call.
    let (mut alpha, mut ok, mut next) = ([k.zero; N], [v.none(); N], [k.zero; N]);
    for i in 0..N {
        // Lanes outside [0, sigma_cut] are masked off below, so the clamp is not needed.
        let g = exp_in_range(v, &k.exp, -sig[i]);
        alpha[i] = v.min(e.opacity * g, k.alpha_max);
        ok[i] = near[i] & v.ge(sig[i], k.zero) & v.ge(alpha[i], k.alpha_min);
        next[i] = st.t[b[i]] * (k.one - alpha[i]);
    }
    for i in 0..N {
        let stop = ok[i] & v.lt(next[i], k.t_min);
        if v.any(stop) {
            st.done[b[i]] = st.done[b[i]] | stop;
            st.active -= v.count(stop) as usize;
        }
        let blend = ok[i] & !stop;
        let (b, t) = (b[i], st.t[b[i]]);
        let w = alpha[i] * t;
        st.red[b] = v.select(blend, st.red[b] + e.rgb[0] * w, st.red[b]);
        st.green[b] = v.select(blend, st.green[b] + e.rgb[1] * w, st.green[b]);
        st.blue[b] = v.select(blend, st.blue[b] + e.rgb[2] * w, st.blue[b]);
        st.depth[b] = v.select(blend, st.depth[b] + e.z * w, st.depth[b]);
        st.t[b] = v.select(blend, next[i], t);
        st.last[b] = v.select_i(blend, e.pos, st.last[b]);
        st.blended[b] = v.count_lanes(st.blended[b], blend);
    }
}

/// Composites one tile front to back, as [`super::scalar::forward_tile_into`] with
/// [`exp`](super::super::simd::exp).
///
/// Per entry, the blocks with a lane left by the ellipse test are listed first (`σ` and the
/// test are short), then blended two at a time ([`blend_blocks`]).
#[inline(always)]
fn forward_tile_into<V: Simd>(
    v: V,
    frame: &Frame,
    tile: usize,
    ids: &[u32],
    splats: &[Splat],
    background: [f32; 3],
    out: TileOut<'_>,
) -> Counters {
    let rect = TileRect::new(frame, tile);
    let (zero, one) = (v.splat(0.0), v.splat(1.0));
    let mut st = Blend::<V> {
        t: [one; BLOCKS],
        done: [v.none(); BLOCKS],
        red: [zero; BLOCKS],
        green: [zero; BLOCKS],
        blue: [zero; BLOCKS],
        depth: [zero; BLOCKS],
        last: [v.splat_i(0); BLOCKS],
        blended: [v.splat_i(0); BLOCKS],
        active: rect.pixels(),
    };
    let mut counters = Counters::default();
    let px = pixel_columns(v, &rect);
    let (alpha_max, alpha_min, t_min) =
        std::hint::black_box((v.splat(ALPHA_MAX), v.splat(ALPHA_MIN), v.splat(T_MIN)));
    let k = Consts {
        exp: ExpConsts::opaque(v),
        zero,
        one,
        alpha_max,
        alpha_min,
        t_min,
    };
    // The blocks an entry meets with a lane left: index, σ and lanes.
    let mut todo_b = [0usize; BLOCKS];
    let mut todo_sig = [zero; BLOCKS];
    let mut todo_near = [v.none(); BLOCKS];
    for (j, &id) in ids.iter().enumerate() {
        if st.active == 0 {
            break;
        }
        let s = &splats[id as usize];
        let Some([x0, y0, x1, y1]) = rect.clip(s.bbox) else {
            continue;
        };
        counters.evaluations += u64::from((x1 - x0 + 1) * (y1 - y0 + 1));
        let (h0, h1, cols) = columns(v, &rect, &px, s, x0, x1);
        let cut = v.splat(s.sigma_cut);
        // Rows and columns of the tile, bounded so that `b` is seen to be in range.
        let (ry0, ry1) = (y0 - rect.y0, (y1 - rect.y0).min(TILE - 1));
        let h1 = h1.min(HALVES - 1);
        let mut n = 0;
        for ry in ry0..ry1 + 1 {
            let dy = ((rect.y0 + ry) as f32 + 0.5) - s.v;
            let cdy2 = s.c * dy * dy;
            for (h, col) in (h0..).zip(&cols[h0..h1 + 1]) {
                let b = ry as usize * HALVES + h;
                let sig = sigma(v, col, cdy2, dy);
                let near = col.inside & !st.done[b] & v.le(sig, cut);
                if v.any(near) {
                    // At most one visit per block, so `n < BLOCKS` here.
                    todo_b[n] = b;
                    todo_sig[n] = sig;
                    todo_near[n] = near;
                    n += 1;
                }
            }
        }
        if n == 0 {
            continue;
        }
        let e = Entry {
            opacity: v.splat(s.opacity),
            rgb: s.rgb.map(|c| v.splat(c)),
            z: v.splat(s.z),
            pos: v.splat_i(j as i32 + 1),
        };
        let mut i = 0;
        while i + 1 < n {
            let (b, sig, near) = (
                [todo_b[i], todo_b[i + 1]],
                [todo_sig[i], todo_sig[i + 1]],
                [todo_near[i], todo_near[i + 1]],
            );
            blend_blocks(v, &k, &e, &mut st, b, sig, near);
            i += 2;
        }
        if i < n {
            blend_blocks(
                v,
                &k,
                &e,
                &mut st,
                [todo_b[i]],
                [todo_sig[i]],
                [todo_near[i]],
            );
        }
    }
    for b in 0..BLOCKS {
        counters.blended += v
            .to_array_i(st.blended[b])
            .iter()
            .map(|&n| u64::from(n as u32))
            .sum::<u64>();
        let (tb, lb) = (v.to_array(st.t[b]), v.to_array_i(st.last[b]));
        let (r, g, bl, d) = (
            v.to_array(st.red[b]),
            v.to_array(st.green[b]),
            v.to_array(st.blue[b]),
            v.to_array(st.depth[b]),
        );
        for l in 0..W {
            let k = b * W + l;
            out.color[k] = [
                r[l] + tb[l] * background[0],
                g[l] + tb[l] * background[1],
                bl[l] + tb[l] * background[2],
            ];
            out.depth[k] = d[l];
            out.final_t[k] = tb[l];
            out.last[k] = lb[l] as u32;
        }
    }
    counters
}

/// [`backward_tile_into`] as a [`Kernel`], to be compiled for the CPU's instruction set.
pub(crate) struct Backward<'a> {
    pub frame: &'a Frame,
    pub tile: usize,
    pub ids: &'a [u32],
    pub splats: &'a [Splat],
    pub background: [f32; 3],
    pub final_t: &'a [f32],
    pub last: &'a [u32],
    pub grads: PixelGrads<'a>,
    pub out: &'a mut [SplatGrads],
}

impl Kernel for Backward<'_> {
    type Output = ();

    #[inline(always)]
    fn run<V: Simd>(self, v: V) {
        if self.grads.alpha.is_some() || self.grads.depth.is_some() {
            backward_tile_into::<V, true>(v, self);
        } else {
            backward_tile_into::<V, false>(v, self);
        }
    }
}

/// Backward of [`forward_tile_into`], as [`super::scalar::backward_tile_into`] with
/// [`exp`](super::super::simd::exp): writes
/// the gradient of each list entry's record into `out` (entries past the tile's last contributor
/// are left as they are). `EXTRA`: whether the alpha or depth image has a gradient (without, their
/// terms are zero and skipped).
///
/// The same quantities as the reference, regrouped so that a block costs fewer operations (the
/// sums differ from the reference's by rounding only):
/// - per lane, `B = Σ_k behind_k · dL/dout_k` is carried instead of the five outputs behind the
///   entry (`B ← α F + (1 - α) B = B + α (F - B)` with `F = Σ_k f_k dL/dout_k`), so that
///   `dL/dα = T (F - B)`;
/// - the conic and mean gradients are taken from per-lane moments of `e = -dL/dσ`:
///   `Σ e`, `Σ e dx`, `Σ e dy`, `Σ e dx²`, `Σ e dx dy`, `Σ e dy²`, combined with the entry's
///   constants once after the sums (`dL/du = a Σ e dx + b Σ e dy`, `dL/da = -½ Σ e dx²`, …,
///   `dL/do = Σ e / o`, since `e = dL/dα · α` and `α = o exp(-σ)` where the cap is inactive);
/// - the entry's sums across lanes are taken eight at a time ([`Simd::sum8`]).
#[inline(always)]
fn backward_tile_into<V: Simd, const EXTRA: bool>(v: V, k: Backward<'_>) {
    let rect = TileRect::new(k.frame, k.tile);
    let width = k.frame.width as usize;
    let (zero, one) = (v.splat(0.0), v.splat(1.0));
    let ek = ExpConsts::opaque(v);
    let (alpha_max, alpha_min) = std::hint::black_box((v.splat(ALPHA_MAX), v.splat(ALPHA_MIN)));
    // Per lane: dL/d(r, g, b, alpha, depth).
    let mut dl = [[[0.0f32; W]; BLOCKS]; 5];
    let mut max_last = 0u32;
    for lane in 0..LANES {
        let (b, l) = (lane / W, lane % W);
        max_last = max_last.max(k.last[lane]);
        let (x, y) = (rect.x0 + (lane as u32 % TILE), rect.y0 + lane as u32 / TILE);
        if x >= rect.x_end || y >= rect.y_end {
            continue;
        }
        let p = y as usize * width + x as usize;
        let c = k.grads.color[p];
        let d = [
            c[0],
            c[1],
            c[2],
            k.grads.alpha.map_or(0.0, |a| a[p]),
            k.grads.depth.map_or(0.0, |d| d[p]),
        ];
        for (q, d) in d.into_iter().enumerate() {
            dl[q][b][l] = d;
        }
    }
    let lanes = |i: usize| -> [f32; W] { k.final_t[i * W..(i + 1) * W].try_into().unwrap() };
    let mut t: [V::F; BLOCKS] = std::array::from_fn(|b| v.lanes(lanes(b)));
    let last: [V::I; BLOCKS] =
        std::array::from_fn(|b| v.lanes_i(std::array::from_fn(|l| k.last[b * W + l] as i32)));
    let dl: [[V::F; BLOCKS]; 5] = dl.map(|q| q.map(|x| v.lanes(x)));
    // Behind the last entry: the background (alpha and depth 0).
    let bg = k.background.map(|c| v.splat(c));
    let mut behind: [V::F; BLOCKS] =
        std::array::from_fn(|b| (bg[0] * dl[0][b] + bg[1] * dl[1][b]) + bg[2] * dl[2][b]);
    let px = pixel_columns(v, &rect);
    for j in (0..max_last as usize).rev() {
        let s = &k.splats[k.ids[j] as usize];
        let Some([x0, y0, x1, y1]) = rect.clip(s.bbox) else {
            continue;
        };
        let jv = v.splat_i(j as i32);
        let (h0, h1, cols) = columns(v, &rect, &px, s, x0, x1);
        let (cut, opacity) = (v.splat(s.sigma_cut), v.splat(s.opacity));
        let [fr, fg, fb] = s.rgb.map(|f| v.splat(f));
        let fz = v.splat(s.z);
        // Per lane sums: r, g, b, Σ e, Σ e dx, Σ e dy, Σ e dx², Σ e dx dy, then Σ e dy², z.
        let mut acc = [zero; W];
        let (mut syy, mut acc_z) = (zero, zero);
        // Rows and columns of the tile, bounded so that `b` is seen to be in range.
        let (ry0, ry1) = (y0 - rect.y0, (y1 - rect.y0).min(TILE - 1));
        let h1 = h1.min(HALVES - 1);
        for ry in ry0..ry1 + 1 {
            let dy = ((rect.y0 + ry) as f32 + 0.5) - s.v;
            let cdy2 = s.c * dy * dy;
            let dyv = v.splat(dy);
            for (h, col) in (h0..).zip(&cols[h0..h1 + 1]) {
                let b = ry as usize * HALVES + h;
                let sig = sigma(v, col, cdy2, dy);
                let near = col.inside & v.gt_i(last[b], jv) & v.le(sig, cut);
                if !v.any(near) {
                    continue;
                }
                // Lanes outside [0, sigma_cut] are masked off below, so the clamp is not needed.
                let g = exp_in_range(v, &ek, -sig);
                let og = opacity * g;
                let alpha = v.min(og, alpha_max);
                let ok = near & v.ge(sig, zero) & v.ge(alpha, alpha_min);
                if !v.any(ok) {
                    continue;
                }
                // Lanes that do not blend get α = 0, which leaves T and B unchanged exactly
                // (x / 1 = x, x + 0·d = x for finite d) and contributes nothing.
                let alpha = v.select(ok, alpha, zero);
                let tj = t[b] / (one - alpha);
                t[b] = tj;
                let w = alpha * tj;
                let mut f = (fr * dl[0][b] + fg * dl[1][b]) + fb * dl[2][b];
                if EXTRA {
                    f = (f + dl[3][b]) + fz * dl[4][b];
                }
                let diff = f - behind[b];
                behind[b] = behind[b] + alpha * diff;
                acc[0] = acc[0] + w * dl[0][b];
                acc[1] = acc[1] + w * dl[1][b];
                acc[2] = acc[2] + w * dl[2][b];
                if EXTRA {
                    acc_z = acc_z + w * dl[4][b];
                }
                // e = dL/dα · α = -dL/dσ, zero where the cap is active (and where not blended).
                // The moments multiply it by dx and dy only, which are finite, so masked lanes
                // add exact zeros.
                let live = ok & !v.gt(og, alpha_max);
                let e = v.select(live, diff * tj * alpha, zero);
                let (ex, ey) = (e * col.dx, e * dyv);
                acc[3] = acc[3] + e;
                acc[4] = acc[4] + ex;
                acc[5] = acc[5] + ey;
                acc[6] = acc[6] + ex * col.dx;
                acc[7] = acc[7] + ex * dyv;
                syy = syy + ey * dyv;
            }
        }
        let [r, g, b, se, sx, sy, sxx, sxy] = v.to_array(v.sum8(acc));
        let syy = v.sum(syy);
        k.out[j] = SplatGrads {
            u: s.a * sx + s.b * sy,
            v: s.b * sx + s.c * sy,
            a: 0.0 - 0.5 * sxx,
            b: 0.0 - sxy,
            c: 0.0 - 0.5 * syy,
            // Σ e = Σ dL/dα · o exp(-σ) (a lane that blends has σ <= sigma_cut, so o > 0).
            opacity: if se == 0.0 { 0.0 } else { se / s.opacity },
            rgb: [r, g, b],
            z: if EXTRA { v.sum(acc_z) } else { 0.0 },
        };
    }
}
