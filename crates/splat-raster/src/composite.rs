//! Per-tile compositing kernels: front-to-back blending of a tile's depth-ordered list over a
//! block of 16×16 pixels (Gaussian-major, one lane per pixel), and its back-to-front backward
//! pass that recovers each pixel's transmittance by division.

use crate::project::{ALPHA_MAX, ALPHA_MIN, Frame, Splat, SplatGrad, T_MIN, TILE};

/// Pixels per tile.
pub(crate) const LANES: usize = (TILE * TILE) as usize;

/// `σ = 0.5 (a dx² + c dy²) + b dx dy` with `d = pixel centre − projected mean`.
#[inline(always)]
fn sigma(s: &Splat, px: f32, py: f32) -> f32 {
    let dx = px - s.u;
    let dy = py - s.v;
    0.5 * (s.a * dx * dx + s.c * dy * dy) + s.b * dx * dy
}

/// `exp(x)` for `x <= 0`, branch-free so that loops over lanes vectorise: Cody–Waite range
/// reduction and the Cephes `expf` polynomial (about 1 ulp; the inputs are clamped to [-87, 0], so
/// NaN gives `exp(-87)`). Forward and backward use this same function, so they make the same
/// decisions at every pixel.
#[inline(always)]
pub(crate) fn exp_neg(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const C1: f32 = 0.693_359_4;
    const C2: f32 = -2.121_944_4e-4;
    // 1.5 * 2^23: adding it rounds to an integer held in the low mantissa bits.
    const MAGIC: f32 = 12_582_912.0;
    let x = if x > -87.0 { x.min(0.0) } else { -87.0 };
    let shifted = x * LOG2E + MAGIC;
    let k = shifted - MAGIC;
    let ki = shifted.to_bits() as i32 - MAGIC.to_bits() as i32;
    let r = x - k * C1 - k * C2;
    let z = r * r;
    let p = ((((1.987_569_1e-4 * r + 1.398_199_9e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2) * r
        + 1.666_666_5e-1)
        * r
        + 0.5;
    let y = p * z + r + 1.0;
    y * f32::from_bits(((ki + 127) << 23) as u32)
}

/// SPEC §3 alpha at a pixel with power `sig`, as `(α, exp(-σ), blendable)`: `blendable` is false
/// when the pixel is skipped (σ < 0, σ beyond the Gaussian's cut-off, or α < 1/255).
///
/// `sigma_cut` is chosen so that every pixel beyond it has `α < 1/255` anyway, so the test is
/// that of the plain formula.
#[inline(always)]
fn alpha_at(s: &Splat, sig: f32) -> (f32, f32, bool) {
    let g = exp_neg(-sig);
    let alpha = (s.opacity * g).min(ALPHA_MAX);
    let ok = (sig >= 0.0) & (sig <= s.sigma_cut) & (alpha >= ALPHA_MIN);
    (alpha, g, ok)
}

/// Pixel-centre coordinates of a tile's lanes and how many lanes lie inside the image.
struct Lanes {
    px: [f32; LANES],
    py: [f32; LANES],
    inside: [bool; LANES],
    count: usize,
}

impl Lanes {
    fn new(frame: &Frame, tile: usize) -> Self {
        let x0 = (tile % frame.tiles_x as usize) as u32 * TILE;
        let y0 = (tile / frame.tiles_x as usize) as u32 * TILE;
        let mut px = [0.0; LANES];
        let mut py = [0.0; LANES];
        let mut inside = [false; LANES];
        let mut count = 0;
        for l in 0..LANES {
            let x = x0 + l as u32 % TILE;
            let y = y0 + l as u32 / TILE;
            px[l] = x as f32 + 0.5;
            py[l] = y as f32 + 0.5;
            inside[l] = x < frame.width && y < frame.height;
            count += usize::from(inside[l]);
        }
        Self {
            px,
            py,
            inside,
            count,
        }
    }

    /// Row-major image index of lane `l` (only meaningful when inside).
    fn pixel(frame: &Frame, tile: usize, l: usize) -> usize {
        let x = (tile % frame.tiles_x as usize) * TILE as usize + l % TILE as usize;
        let y = (tile / frame.tiles_x as usize) * TILE as usize + l / TILE as usize;
        y * frame.width as usize + x
    }
}

/// One tile's forward output, tile-major (lane order).
pub(crate) struct TileOut<'a> {
    pub color: &'a mut [[f32; 3]],
    pub depth: &'a mut [f32],
    pub final_t: &'a mut [f32],
    /// One past the list position of the last blended Gaussian, per lane (0 = none).
    pub last: &'a mut [u32],
}

/// Work counters of a forward pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Counters {
    /// Gaussian-pixel pairs the inner loop visited (list entries processed × pixels in tile).
    pub evaluations: u64,
    /// Gaussian-pixel pairs actually blended.
    pub blended: u64,
}

/// Composites one tile front to back. Background is added to the colour.
///
/// Gaussian-major: for each list entry, `σ` is computed for every lane (pixel) in a loop that
/// vectorises, then only lanes inside the Gaussian's cut-off are blended; a lane that stops keeps
/// its state; the tile ends when all lanes have stopped.
pub(crate) fn forward_tile(
    frame: &Frame,
    tile: usize,
    ids: &[u32],
    splats: &[Splat],
    background: [f32; 3],
    out: TileOut<'_>,
) -> Counters {
    let lanes = Lanes::new(frame, tile);
    let mut t = [1.0f32; LANES];
    let mut done = lanes.inside.map(|inside| !inside);
    let mut red = [0.0f32; LANES];
    let mut green = [0.0f32; LANES];
    let mut blue = [0.0f32; LANES];
    let mut depth = [0.0f32; LANES];
    let mut last = [0u32; LANES];
    let mut sig = [0.0f32; LANES];
    let mut active = lanes.count;
    let mut counters = Counters::default();
    for (j, &id) in ids.iter().enumerate() {
        if active == 0 {
            break;
        }
        let s = &splats[id as usize];
        let pos = j as u32 + 1;
        counters.evaluations += lanes.count as u64;
        // σ for every lane (vectorises), then the few lanes inside the cut-off.
        for ((out, &px), &py) in sig.iter_mut().zip(&lanes.px).zip(&lanes.py) {
            *out = sigma(s, px, py);
        }
        for l in 0..LANES {
            let inside = sig[l] <= s.sigma_cut;
            if !inside || done[l] {
                continue;
            }
            let (alpha, _, ok) = alpha_at(s, sig[l]);
            if !ok {
                continue;
            }
            let next = t[l] * (1.0 - alpha);
            if next < T_MIN {
                done[l] = true;
                active -= 1;
                continue;
            }
            let w = alpha * t[l];
            red[l] += s.rgb[0] * w;
            green[l] += s.rgb[1] * w;
            blue[l] += s.rgb[2] * w;
            depth[l] += s.z * w;
            t[l] = next;
            last[l] = pos;
            counters.blended += 1;
        }
    }
    for l in 0..LANES {
        out.color[l] = [
            red[l] + t[l] * background[0],
            green[l] + t[l] * background[1],
            blue[l] + t[l] * background[2],
        ];
    }
    out.depth.copy_from_slice(&depth);
    out.final_t.copy_from_slice(&t);
    out.last.copy_from_slice(&last);
    counters
}

/// Per-pixel loss gradients of the three outputs, row-major.
#[derive(Clone, Copy)]
pub(crate) struct PixelGrads<'a> {
    pub color: &'a [[f32; 3]],
    pub alpha: Option<&'a [f32]>,
    pub depth: Option<&'a [f32]>,
}

/// Backward of [`forward_tile`]: writes the gradient of each list entry's record into `out`
/// (same length as `ids`; entries past the tile's last contributor are left zero).
#[allow(clippy::too_many_arguments)]
pub(crate) fn backward_tile(
    frame: &Frame,
    tile: usize,
    ids: &[u32],
    splats: &[Splat],
    background: [f32; 3],
    final_t: &[f32],
    last: &[u32],
    grads: PixelGrads<'_>,
    out: &mut [SplatGrad],
) {
    let lanes = Lanes::new(frame, tile);
    let mut t = [0.0f32; LANES];
    t.copy_from_slice(final_t);
    // Per lane: dL/d(r, g, b, alpha, depth) and the normalised colour behind the current entry.
    let mut dl = [[0.0f32; 5]; LANES];
    let mut behind = [[0.0f32; 5]; LANES];
    let mut max_last = 0usize;
    for l in 0..LANES {
        if !lanes.inside[l] {
            continue;
        }
        let p = Lanes::pixel(frame, tile, l);
        let c = grads.color[p];
        dl[l] = [
            c[0],
            c[1],
            c[2],
            grads.alpha.map_or(0.0, |a| a[p]),
            grads.depth.map_or(0.0, |d| d[p]),
        ];
        behind[l] = [background[0], background[1], background[2], 0.0, 0.0];
        max_last = max_last.max(last[l] as usize);
    }
    for j in (0..max_last).rev() {
        let s = &splats[ids[j] as usize];
        let feat = [s.rgb[0], s.rgb[1], s.rgb[2], 1.0, s.z];
        let mut acc = SplatGrad::default();
        for l in 0..LANES {
            if j >= last[l] as usize {
                continue;
            }
            let (px, py) = (lanes.px[l], lanes.py[l]);
            let (alpha, g, ok) = alpha_at(s, sigma(s, px, py));
            if !ok {
                continue;
            }
            let capped = s.opacity * g > ALPHA_MAX;
            let tj = t[l] / (1.0 - alpha);
            t[l] = tj;
            let w = alpha * tj;
            let d = &dl[l];
            let bh = &mut behind[l];
            let mut d_alpha = 0.0f32;
            for k in 0..5 {
                d_alpha += (feat[k] - bh[k]) * d[k];
                bh[k] = alpha * feat[k] + (1.0 - alpha) * bh[k];
            }
            d_alpha *= tj;
            for (a, dc) in acc.rgb.iter_mut().zip(d) {
                *a += w * dc;
            }
            acc.z += w * d[4];
            if capped {
                continue;
            }
            // α = o·exp(-σ): dα/do = exp(-σ), dα/dσ = -α.
            acc.opacity += d_alpha * g;
            let d_sig = -d_alpha * alpha;
            let dx = px - s.u;
            let dy = py - s.v;
            acc.a += d_sig * 0.5 * dx * dx;
            acc.b += d_sig * dx * dy;
            acc.c += d_sig * 0.5 * dy * dy;
            acc.u -= d_sig * (s.a * dx + s.b * dy);
            acc.v -= d_sig * (s.b * dx + s.c * dy);
        }
        out[j] = acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_neg_is_within_two_ulp_of_libm() {
        let mut x = 0.0f32;
        while x > -20.0 {
            let (a, b) = (exp_neg(x), x.exp());
            assert!((a - b).abs() <= 2.5e-7 * b, "x={x}: {a} vs {b}");
            x -= 0.000_37;
        }
        assert_eq!(exp_neg(0.0), 1.0);
        assert!(exp_neg(f32::NAN).is_finite());
        assert!(exp_neg(-1e30) >= 0.0 && exp_neg(-1e30) < 1e-37);
    }
}
