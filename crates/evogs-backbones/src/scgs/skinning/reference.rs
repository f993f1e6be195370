//! The plain skinning, one neighbour at a time: each control point's radius, weight and local
//! rotation recomputed for every Gaussian it blends, the rotation's gradient taken per
//! neighbour. It is the reference the prepared skinning of [`super`] is tested against
//! (`tests/scgs_gradients.rs`), kept as gsplat keeps a plain twin beside each fast kernel; it
//! is not used in training.

use super::{
    Controls, LOCAL, NODE_OUTPUT, ROW, Share, SkinGrads, Sums, TRANSLATION, WEIGHT_EPS,
    add_blend_terms, blend, dot, finish_row, local_quaternion, rotate, rotate_back, rotate_grad_q,
    sub, wide,
};
use crate::scgs::knn::Neighbours;

/// The shares of a Gaussian's neighbours and the sum of their unnormalised weights.
fn shares(x: [f64; 3], index: &[u32], controls: Controls<'_>, out: &mut [Share]) -> f64 {
    let mut total = 0.0;
    for (share, &c) in out.iter_mut().zip(index) {
        let c = c as usize;
        let v = sub(x, wide(controls.positions[c]));
        let d2 = dot(v, v);
        let r2 = (2.0 * f64::from(controls.log_radii[c])).exp();
        // d² = 0 is weight 1 whatever the radius (0/0 when the radius underflows too).
        let e = if d2 == 0.0 {
            1.0
        } else {
            (-d2 / (2.0 * r2)).exp()
        };
        let a = 1.0 / (1.0 + (-f64::from(controls.weight_logits[c])).exp());
        let raw = e * a + WEIGHT_EPS;
        total += raw;
        *share = Share {
            c,
            v,
            d2,
            r2,
            e,
            a,
            raw,
        };
    }
    total
}

/// A control point's blended target `R_c (x − p_c) + p_c + T_c`.
fn target(share: &Share, controls: Controls<'_>, node: &[f32]) -> [f64; 3] {
    let p = wide(controls.positions[share.c]);
    let t = &node[TRANSLATION];
    let rv = local_quaternion(node).map_or(share.v, |q| rotate(q, share.v));
    std::array::from_fn(|i| rv[i] + p[i] + f64::from(t[i]))
}

/// [`super::skin_into`], computed plainly.
///
/// # Panics
/// When the sizes disagree, as [`super::skin_into`].
pub fn skin_into(
    means: &[[f32; 3]],
    nb: &Neighbours,
    controls: Controls<'_>,
    nodes: &[f32],
    out: &mut Vec<f32>,
) {
    assert_eq!(nb.rows(), means.len(), "neighbours of every Gaussian");
    assert_eq!(nodes.len(), controls.positions.len() * NODE_OUTPUT);
    let k = nb.k;
    out.clear();
    out.resize(means.len() * ROW, 0.0);
    let mut sh = vec![Share::default(); k];
    for (i, (row, &x)) in out.chunks_exact_mut(ROW).zip(means).enumerate() {
        let x = wide(x);
        let total = shares(x, &nb.index[i * k..(i + 1) * k], controls, &mut sh);
        let mut acc = [0f64; ROW];
        for s in &sh {
            let w = s.raw / total;
            let node = &nodes[s.c * NODE_OUTPUT..(s.c + 1) * NODE_OUTPUT];
            blend(&mut acc, w, target(s, controls, node), node);
        }
        finish_row(acc, x, row);
    }
}

/// [`super::skin_backward`], computed plainly: every neighbour's rotation gradient and position
/// term taken on its own.
///
/// # Panics
/// When the sizes disagree, as [`super::skin_into`].
pub fn skin_backward(
    means: &[[f32; 3]],
    nb: &Neighbours,
    controls: Controls<'_>,
    nodes: &[f32],
    d_rows: &[f32],
) -> SkinGrads {
    let m = controls.positions.len();
    assert_eq!(nb.rows(), means.len(), "neighbours of every Gaussian");
    assert_eq!(nodes.len(), m * NODE_OUTPUT);
    assert_eq!(d_rows.len(), means.len() * ROW);
    let k = nb.k;
    let mut sums = Sums::zeros(m);
    let mut sh = vec![Share::default(); k];
    let mut h = vec![0f64; k];
    for (i, &x) in means.iter().enumerate() {
        let g = &d_rows[i * ROW..(i + 1) * ROW];
        let gx = [g[0], g[1], g[2]].map(f64::from);
        let total = shares(wide(x), &nb.index[i * k..(i + 1) * k], controls, &mut sh);
        let mut mean_h = 0.0;
        for (s, hs) in sh.iter().zip(&mut h) {
            let w = s.raw / total;
            let node = &nodes[s.c * NODE_OUTPUT..(s.c + 1) * NODE_OUTPUT];
            let dn = &mut sums.nodes[s.c * NODE_OUTPUT..(s.c + 1) * NODE_OUTPUT];
            *hs = add_blend_terms(dn, g, w, target(s, controls, node), node);
            // Through R_c (x − p_c) + p_c: to the local quaternion and the position.
            let gy = gx.map(|v| w * v);
            let back = match local_quaternion(node) {
                Some(q) => {
                    let dq = rotate_grad_q(q, s.v, gy);
                    for (d, v) in dn[LOCAL].iter_mut().zip(dq) {
                        *d += v;
                    }
                    rotate_back(q, gy)
                }
                None => gy,
            };
            for c in 0..3 {
                sums.positions[s.c * 3 + c] += gy[c] - back[c];
            }
            mean_h += w * *hs;
        }
        sums.add_weight_terms(&sh, &h, mean_h, total);
    }
    sums.narrow()
}
