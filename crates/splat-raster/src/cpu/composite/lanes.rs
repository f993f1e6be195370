//! The fast compositing kernels: the same per-pixel arithmetic as [`super::scalar`], eight pixels
//! of a tile row at a time (the lanes of a [`Simd`] build), with the vectorised [`exp`].
//!
//! A tile is 32 blocks of 8 pixels (row `y`, half `h`), stored in lane order, so block `2y + h`
//! holds lanes `16y + 8h .. 16y + 8h + 8`. For each list entry, the blocks that meet its bounding
//! box are visited; in each, `σ` is computed for the eight pixels exactly as the reference does
//! and the exact ellipse test `σ <= sigma_cut` (with the bounding box and the pixels still
//! running) masks the lanes; a block with no lane left is skipped before the `exp`. Lanes are
//! updated by selects, so a lane that is masked off keeps its state bit for bit.
//!
//! With the same `exp`, the forward kernel gives the reference kernel's outputs bit for bit (the
//! same operations in the same order per pixel). The backward kernel sums each entry's gradient
//! over the pixels per lane and then across the lanes in a fixed order, so its sums differ from
//! the reference's pixel-by-pixel order by rounding only, and never depend on the thread count.

use super::super::project::{Splat, SplatGrads};
use super::super::simd::{Kernel, Simd, W, exp};
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

/// The columns of tile `rect` met by the clipped bounding box `[x0, x1]` of splat `s`.
#[inline(always)]
fn columns<V: Simd>(
    v: V,
    rect: &TileRect,
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
    for (h, col) in cols.iter_mut().enumerate().take(h1 + 1).skip(h0) {
        let first = (h * W) as u32;
        let lo = lx0.saturating_sub(first);
        let hi = (lx1 - first).min(W as u32 - 1);
        let px = v.lanes(std::array::from_fn(|l| {
            (rect.x0 + first + l as u32) as f32 + 0.5
        }));
        let dx = px - v.splat(s.u);
        *col = Column {
            inside: v.range(lo, hi),
            dx,
            adx2: v.splat(s.a) * dx * dx,
            bdx: v.splat(s.b) * dx,
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

/// Composites one tile front to back, as [`super::scalar::forward_tile_into`] with [`exp`].
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
    let mut t = [one; BLOCKS];
    let mut done = [v.none(); BLOCKS];
    let mut red = [zero; BLOCKS];
    let mut green = [zero; BLOCKS];
    let mut blue = [zero; BLOCKS];
    let mut depth = [zero; BLOCKS];
    let mut last = [v.splat_i(0); BLOCKS];
    let mut active = rect.pixels();
    let mut counters = Counters::default();
    for (j, &id) in ids.iter().enumerate() {
        if active == 0 {
            break;
        }
        let s = &splats[id as usize];
        let Some([x0, y0, x1, y1]) = rect.clip(s.bbox) else {
            continue;
        };
        counters.evaluations += u64::from((x1 - x0 + 1) * (y1 - y0 + 1));
        let pos = v.splat_i(j as i32 + 1);
        let (h0, h1, cols) = columns(v, &rect, s, x0, x1);
        let (cut, opacity) = (v.splat(s.sigma_cut), v.splat(s.opacity));
        let rgb = s.rgb.map(|c| v.splat(c));
        let z = v.splat(s.z);
        for y in y0..=y1 {
            let dy = (y as f32 + 0.5) - s.v;
            let cdy2 = s.c * dy * dy;
            let row = (y - rect.y0) as usize * HALVES;
            for (h, col) in cols.iter().enumerate().take(h1 + 1).skip(h0) {
                let b = row + h;
                let sig = sigma(v, col, cdy2, dy);
                let near = col.inside & !done[b] & v.le(sig, cut);
                if !v.any(near) {
                    continue;
                }
                let g = exp(v, -sig);
                let alpha = v.min(opacity * g, v.splat(ALPHA_MAX));
                let ok = near & v.ge(sig, zero) & v.ge(alpha, v.splat(ALPHA_MIN));
                let next = t[b] * (one - alpha);
                let stop = ok & v.lt(next, v.splat(T_MIN));
                if v.any(stop) {
                    done[b] = done[b] | stop;
                    active -= v.count(stop) as usize;
                }
                let blend = ok & !stop;
                let w = alpha * t[b];
                red[b] = v.select(blend, red[b] + rgb[0] * w, red[b]);
                green[b] = v.select(blend, green[b] + rgb[1] * w, green[b]);
                blue[b] = v.select(blend, blue[b] + rgb[2] * w, blue[b]);
                depth[b] = v.select(blend, depth[b] + z * w, depth[b]);
                t[b] = v.select(blend, next, t[b]);
                last[b] = v.select_i(blend, pos, last[b]);
                counters.blended += u64::from(v.count(blend));
            }
        }
    }
    for b in 0..BLOCKS {
        let (tb, lb) = (v.to_array(t[b]), v.to_array_i(last[b]));
        let (r, g, bl, d) = (
            v.to_array(red[b]),
            v.to_array(green[b]),
            v.to_array(blue[b]),
            v.to_array(depth[b]),
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
        backward_tile_into(v, self);
    }
}

/// Backward of [`forward_tile_into`], as [`super::scalar::backward_tile_into`] with [`exp`]: writes the
/// gradient of each list entry's record into `out` (entries past the tile's last contributor
/// are left as they are).
#[inline(always)]
fn backward_tile_into<V: Simd>(v: V, k: Backward<'_>) {
    let rect = TileRect::new(k.frame, k.tile);
    let width = k.frame.width as usize;
    let (zero, one) = (v.splat(0.0), v.splat(1.0));
    // Per lane: dL/d(r, g, b, alpha, depth) and the normalised outputs behind the current entry.
    let mut dl = [[[0.0f32; W]; BLOCKS]; 5];
    let mut bh = [[[0.0f32; W]; BLOCKS]; 5];
    let mut max_last = 0u32;
    for b in 0..BLOCKS {
        for l in 0..W {
            let lane = b * W + l;
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
            let bg = [k.background[0], k.background[1], k.background[2], 0.0, 0.0];
            for q in 0..5 {
                dl[q][b][l] = d[q];
                bh[q][b][l] = bg[q];
            }
        }
    }
    let lanes = |i: usize| -> [f32; W] { k.final_t[i * W..(i + 1) * W].try_into().unwrap() };
    let mut t: [V::F; BLOCKS] = std::array::from_fn(|b| v.lanes(lanes(b)));
    let last: [V::I; BLOCKS] =
        std::array::from_fn(|b| v.lanes_i(std::array::from_fn(|l| k.last[b * W + l] as i32)));
    let dl: [[V::F; BLOCKS]; 5] = dl.map(|q| q.map(|x| v.lanes(x)));
    let mut behind: [[V::F; BLOCKS]; 5] = bh.map(|q| q.map(|x| v.lanes(x)));
    for j in (0..max_last as usize).rev() {
        let s = &k.splats[k.ids[j] as usize];
        let Some([x0, y0, x1, y1]) = rect.clip(s.bbox) else {
            continue;
        };
        let jv = v.splat_i(j as i32);
        let (h0, h1, cols) = columns(v, &rect, s, x0, x1);
        let (cut, opacity) = (v.splat(s.sigma_cut), v.splat(s.opacity));
        let feat = [s.rgb[0], s.rgb[1], s.rgb[2], 1.0, s.z].map(|f| v.splat(f));
        let (sa, sb, sc) = (v.splat(s.a), v.splat(s.b), v.splat(s.c));
        let half = v.splat(0.5);
        // Per lane sums: r, g, b, z, opacity, a, b, c, u, v.
        let mut acc = [zero; 10];
        for y in y0..=y1 {
            let dy = (y as f32 + 0.5) - s.v;
            let cdy2 = s.c * dy * dy;
            let dyv = v.splat(dy);
            let row = (y - rect.y0) as usize * HALVES;
            for (h, col) in cols.iter().enumerate().take(h1 + 1).skip(h0) {
                let b = row + h;
                let sig = sigma(v, col, cdy2, dy);
                let near = col.inside & v.gt_i(last[b], jv) & v.le(sig, cut);
                if !v.any(near) {
                    continue;
                }
                let g = exp(v, -sig);
                let og = opacity * g;
                let alpha = v.min(og, v.splat(ALPHA_MAX));
                let ok = near & v.ge(sig, zero) & v.ge(alpha, v.splat(ALPHA_MIN));
                if !v.any(ok) {
                    continue;
                }
                // Lanes that do not blend get α = 0, which leaves T and the colour behind
                // unchanged exactly (x / 1 = x, 0·f + 1·x = x) and contributes nothing.
                let alpha = v.select(ok, alpha, zero);
                let keep = one - alpha;
                let tj = t[b] / keep;
                t[b] = tj;
                let w = alpha * tj;
                let mut d_alpha = zero;
                for q in 0..5 {
                    let bh = behind[q][b];
                    d_alpha = d_alpha + (feat[q] - bh) * dl[q][b];
                    behind[q][b] = alpha * feat[q] + keep * bh;
                }
                acc[0] = acc[0] + w * dl[0][b];
                acc[1] = acc[1] + w * dl[1][b];
                acc[2] = acc[2] + w * dl[2][b];
                acc[3] = acc[3] + w * dl[4][b];
                // α = o·exp(-σ): dα/do = exp(-σ), dα/dσ = -α; zero where the cap is active.
                let live = ok & !v.gt(og, v.splat(ALPHA_MAX));
                let d_alpha = v.select(live, d_alpha * tj, zero);
                acc[4] = acc[4] + v.select(live, d_alpha * g, zero);
                let d_sig = -(d_alpha * alpha);
                let dx = col.dx;
                let inc = [
                    d_sig * half * dx * dx,
                    d_sig * dx * dyv,
                    d_sig * half * dyv * dyv,
                    d_sig * (sa * dx + sb * dyv),
                    d_sig * (sb * dx + sc * dyv),
                ];
                // Masked lanes hold d_sig = 0, but their products may overflow far outside the
                // ellipse: select, never multiply by the mask.
                acc[5] = acc[5] + v.select(live, inc[0], zero);
                acc[6] = acc[6] + v.select(live, inc[1], zero);
                acc[7] = acc[7] + v.select(live, inc[2], zero);
                acc[8] = acc[8] - v.select(live, inc[3], zero);
                acc[9] = acc[9] - v.select(live, inc[4], zero);
            }
        }
        let sums = acc.map(|a| v.sum(a));
        k.out[j] = SplatGrads {
            u: sums[8],
            v: sums[9],
            a: sums[5],
            b: sums[6],
            c: sums[7],
            opacity: sums[4],
            rgb: [sums[0], sums[1], sums[2]],
            z: sums[3],
        };
    }
}
