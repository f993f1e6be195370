//! The reference compositing kernels: one pixel at a time, Gaussian-major over a tile (for each
//! list entry, the pixels of its bounding box), with `exp` passed in. With `f32::exp` they are
//! the CPU backend's original kernels, kept as the readable definition and to measure the fast
//! kernels of [`super::lanes`] against; with [`crate::cpu::simd::exp`] they make the same blending
//! decisions as the fast ones, pixel for pixel, which the tests compare.

use super::super::project::{Splat, SplatGrads};
use super::{LANES, TileOut, TileRect};
use crate::constants::{ALPHA_MAX, ALPHA_MIN, T_MIN};
use crate::frame::Frame;
use crate::output::Counters;
use crate::output::PixelGrads;

/// `σ = 0.5 (a dx² + c dy²) + b dx dy` with `d = pixel centre − projected mean`.
#[inline(always)]
fn sigma(s: &Splat, px: f32, py: f32) -> f32 {
    let dx = px - s.u;
    let dy = py - s.v;
    0.5 * (s.a * dx * dx + s.c * dy * dy) + s.b * dx * dy
}

/// DESIGN §3 alpha at a pixel with power `sig`, as `(α, exp(-σ), blendable)`: `blendable` is false
/// when the pixel is skipped (σ < 0 or α < 1/255).
#[inline(always)]
fn alpha_at(s: &Splat, sig: f32, exp: impl Fn(f32) -> f32) -> (f32, f32, bool) {
    let g = exp(-sig);
    let alpha = (s.opacity * g).min(ALPHA_MAX);
    let ok = (sig >= 0.0) & (alpha >= ALPHA_MIN);
    (alpha, g, ok)
}

/// Composites one tile front to back. Background is added to the colour.
///
/// Gaussian-major: for each list entry in depth order, the pixels of the tile inside the
/// Gaussian's bounding box are updated (pixels outside it cannot reach α >= 1/255); a pixel that
/// stops keeps its state; the tile ends when all its pixels have stopped.
pub(crate) fn forward_tile_into(
    frame: &Frame,
    tile: usize,
    ids: &[u32],
    splats: &[Splat],
    background: [f32; 3],
    out: TileOut<'_>,
    exp: impl Fn(f32) -> f32 + Copy,
) -> Counters {
    let rect = TileRect::new(frame, tile);
    let mut t = [1.0f32; LANES];
    let mut done = [false; LANES];
    let mut red = [0.0f32; LANES];
    let mut green = [0.0f32; LANES];
    let mut blue = [0.0f32; LANES];
    let mut depth = [0.0f32; LANES];
    let mut last = [0u32; LANES];
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
        let pos = j as u32 + 1;
        counters.evaluations += u64::from((x1 - x0 + 1) * (y1 - y0 + 1));
        for y in y0..=y1 {
            let py = y as f32 + 0.5;
            for x in x0..=x1 {
                let l = rect.lane(x, y);
                if done[l] {
                    continue;
                }
                let sig = sigma(s, x as f32 + 0.5, py);
                // Beyond the cut-off α < 1/255 for certain: skip without evaluating exp.
                let near = sig <= s.sigma_cut;
                if !near {
                    continue;
                }
                let (alpha, _, ok) = alpha_at(s, sig, exp);
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

/// Backward of [`forward_tile_into`]: writes the gradient of each list entry's record into `out`
/// (same length as `ids`; entries past the tile's last contributor are left zero).
///
/// Back to front per pixel: `T` is recovered by division, `T_j = T_{j+1} / (1 - α_j)`, and the
/// normalised colour (and alpha, depth) behind entry `j` is carried along, so that
/// `dL/dα_j = T_j Σ_k (f_k - behind_k) dL/dout_k` over the five outputs (r, g, b, alpha, depth).
#[allow(clippy::too_many_arguments)]
pub(crate) fn backward_tile_into(
    frame: &Frame,
    tile: usize,
    ids: &[u32],
    splats: &[Splat],
    background: [f32; 3],
    final_t: &[f32],
    last: &[u32],
    grads: PixelGrads<'_>,
    out: &mut [SplatGrads],
    exp: impl Fn(f32) -> f32 + Copy,
) {
    let rect = TileRect::new(frame, tile);
    let mut t = [0.0f32; LANES];
    t.copy_from_slice(final_t);
    // Per lane: dL/d(r, g, b, alpha, depth) and the normalised outputs behind the current entry.
    let mut dl = [[0.0f32; 5]; LANES];
    let mut behind = [[0.0f32; 5]; LANES];
    let mut max_last = 0usize;
    for y in rect.y0..rect.y_end {
        for x in rect.x0..rect.x_end {
            let l = rect.lane(x, y);
            let p = y as usize * frame.width as usize + x as usize;
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
    }
    for j in (0..max_last).rev() {
        let s = &splats[ids[j] as usize];
        let Some([x0, y0, x1, y1]) = rect.clip(s.bbox) else {
            continue;
        };
        let feat = [s.rgb[0], s.rgb[1], s.rgb[2], 1.0, s.z];
        let mut acc = SplatGrads::default();
        for y in y0..=y1 {
            let py = y as f32 + 0.5;
            for x in x0..=x1 {
                let l = rect.lane(x, y);
                if j >= last[l] as usize {
                    continue;
                }
                let px = x as f32 + 0.5;
                let sig = sigma(s, px, py);
                let near = sig <= s.sigma_cut;
                if !near {
                    continue;
                }
                let (alpha, g, ok) = alpha_at(s, sig, exp);
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
        }
        out[j] = acc;
    }
}
