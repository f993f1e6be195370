//! Linear blend skinning of Gaussians by their nearest control points, and its gradient.
//!
//! Per Gaussian with canonical mean `x` and K nearest control points `c` (positions `p_c`, log
//! radii `ρ_c`, weight logits `β_c`), SC-GS's `ControlNodeWarp.forward` (`utils/time_utils.py`)
//! with `local_frame` on, as its D-NeRF command runs it:
//!
//! - `w̃_c = exp(−|x − p_c|² / (2 r_c²)) · σ(β_c) + 1e-7`, `r_c = exp(ρ_c)`; `w_c = w̃_c / Σ w̃`;
//! - position row `Σ_c w_c [R_c (x − p_c) + p_c + T_c] − x`, with `R_c` the rotation of the
//!   local quaternion `[1, 0, 0, 0] + L_c` (normalised inside the rotation);
//! - rotation row `Σ_c w_c Q_c` and scale row `Σ_c w_c S_c` (added to the raw quaternion and the
//!   log-scale, `splat_core::DeformedGeometry`).
//!
//! `T, Q, S, L` are the control-point network's four heads at the row's time ([`NODE_OUTPUT`]
//! columns per control point). The Gaussian's mean enters detached (SC-GS: `x.detach()`), so the
//! gradient goes to the heads, the control points' positions, radii and weight logits only.
//! The sums run in f64 per Gaussian; a Gaussian far from every control point gets the ε weights
//! (an even blend), a radius that underflows to zero gives a weight of exactly ε, and neither
//! makes a NaN in the gradient.
//!
//! Each control point's radius, weight `σ(β)`, `p + T` and rotation matrix are prepared once
//! per call, not per (Gaussian, neighbour) pair, and the backward pass chains the rotation's
//! gradient to the quaternion once per control point from per-point sums; [`reference`] is the
//! plain per-pair computation the tests hold this one to.

use rayon::prelude::*;

use super::knn::Neighbours;

pub mod reference;

/// Network outputs per control point: translation 3, rotation residual 4, scale residual 3,
/// local rotation 4.
pub const NODE_OUTPUT: usize = 14;
/// Columns of the translation `T` in a control point's outputs.
pub const TRANSLATION: std::ops::Range<usize> = 0..3;
/// Columns of the rotation residual `Q`.
pub const ROTATION: std::ops::Range<usize> = 3..7;
/// Columns of the scale residual `S`.
pub const SCALE: std::ops::Range<usize> = 7..10;
/// Columns of the local rotation `L` (the quaternion `[1, 0, 0, 0] + L`).
pub const LOCAL: std::ops::Range<usize> = 10..14;
/// Width of a skinned row: position 3, rotation 4, scale 3 (`Layout::GEOMETRY`).
pub const ROW: usize = 10;
/// SC-GS's ε added to every unnormalised weight (`cal_nn_weight`: `+ 1e-7`).
pub const WEIGHT_EPS: f64 = 1e-7;
/// A local quaternion with a squared norm below this is taken as no rotation (no gradient).
const MIN_QUAT_NORM2: f64 = 1e-12;
/// Gaussians per parallel task (fixed, so the gradient's sums are the same on any thread count).
const ROWS_PER_TASK: usize = 1024;

/// The control points' learnable shape: positions (M × 3), log radii (M), weight logits (M).
#[derive(Clone, Copy, Debug)]
pub struct Controls<'a> {
    /// Canonical positions `p`.
    pub positions: &'a [[f32; 3]],
    /// Log radii `ρ`.
    pub log_radii: &'a [f32],
    /// Weight logits `β` (the weight is `σ(β)`).
    pub weight_logits: &'a [f32],
}

/// Gradients of [`skin_backward`].
#[derive(Clone, Debug, PartialEq)]
pub struct SkinGrads {
    /// dL/d(network outputs), M × [`NODE_OUTPUT`].
    pub nodes: Vec<f32>,
    /// dL/d(positions), M × 3.
    pub positions: Vec<f32>,
    /// dL/d(log radii), M.
    pub log_radii: Vec<f32>,
    /// dL/d(weight logits), M.
    pub weight_logits: Vec<f32>,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn wide(v: [f32; 3]) -> [f64; 3] {
    v.map(f64::from)
}

/// The quaternion `[1, 0, 0, 0] + L` of a control point's outputs, `None` when it is (nearly)
/// zero.
fn local_quaternion(node: &[f32]) -> Option<[f64; 4]> {
    let l = &node[LOCAL];
    let q = [
        1.0 + f64::from(l[0]),
        f64::from(l[1]),
        f64::from(l[2]),
        f64::from(l[3]),
    ];
    (q.iter().map(|v| v * v).sum::<f64>() >= MIN_QUAT_NORM2).then_some(q)
}

/// `R(q) v` for the rotation of the (unnormalised) quaternion `q = (w, u)`:
/// `v + 2/|q|² (w (u × v) + u × (u × v))`.
pub fn rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let (w, u) = (q[0], [q[1], q[2], q[3]]);
    let n = q.iter().map(|x| x * x).sum::<f64>();
    let uv = cross(u, v);
    let uuv = cross(u, uv);
    let s = 2.0 / n;
    std::array::from_fn(|i| v[i] + s * (w * uv[i] + uuv[i]))
}

/// `R(q)ᵀ g`: the rotation of the conjugate quaternion.
pub fn rotate_back(q: [f64; 4], g: [f64; 3]) -> [f64; 3] {
    rotate([q[0], -q[1], -q[2], -q[3]], g)
}

/// `gᵀ ∂(R(q) v)/∂q`, the gradient of `g · R(q) v` with respect to the four values of `q`.
pub fn rotate_grad_q(q: [f64; 4], v: [f64; 3], g: [f64; 3]) -> [f64; 4] {
    let (w, u) = (q[0], [q[1], q[2], q[3]]);
    let n = q.iter().map(|x| x * x).sum::<f64>();
    let s = 2.0 / n;
    // R v = v + s A with A = w (u × v) + u (u · v) − v |u|².
    let (uv, uu, udv) = (cross(u, v), dot(u, u), dot(u, v));
    let a: [f64; 3] = std::array::from_fn(|i| w * uv[i] + u[i] * udv - v[i] * uu);
    let (gu, gv) = (dot(g, u), dot(g, v));
    let vg = cross(v, g);
    let ga_w = dot(g, uv);
    let ga_u: [f64; 3] =
        std::array::from_fn(|i| w * vg[i] + g[i] * udv + gu * v[i] - 2.0 * gv * u[i]);
    // ∂s/∂q = −4 q / |q|⁴.
    let ds = -4.0 * dot(g, a) / (n * n);
    [
        s * ga_w + ds * q[0],
        s * ga_u[0] + ds * q[1],
        s * ga_u[1] + ds * q[2],
        s * ga_u[2] + ds * q[3],
    ]
}

/// One neighbour's share of a Gaussian's blend.
#[derive(Clone, Copy, Default)]
struct Share {
    /// The control point.
    c: usize,
    /// `x − p_c`.
    v: [f64; 3],
    /// `|x − p_c|²`.
    d2: f64,
    /// `r_c²`.
    r2: f64,
    /// `exp(−d² / (2 r²))`.
    e: f64,
    /// `σ(β_c)`.
    a: f64,
    /// The unnormalised weight `e a + ε`.
    raw: f64,
}

/// What a control point brings to every blend it is in, computed once per call: SC-GS
/// evaluates the radius, the weight and the local rotation per (Gaussian, neighbour) pair;
/// here they are made once for each of the few hundred control points.
#[derive(Clone, Copy)]
struct Prepared {
    /// Canonical position `p`.
    p: [f64; 3],
    /// `r²`.
    r2: f64,
    /// `2 r²` (the exponent's divisor).
    two_r2: f64,
    /// `σ(β)`.
    a: f64,
    /// `p + T`.
    pt: [f64; 3],
    /// The local rotation `R` (row-major), `None` when its quaternion is (nearly) zero.
    rot: Option<[[f64; 3]; 3]>,
}

/// The rotation matrix of the (unnormalised) quaternion `q`, the same map as [`rotate`].
fn matrix(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    let s = 2.0 / q.iter().map(|v| v * v).sum::<f64>();
    [
        [
            1.0 - s * (y * y + z * z),
            s * (x * y - w * z),
            s * (x * z + w * y),
        ],
        [
            s * (x * y + w * z),
            1.0 - s * (x * x + z * z),
            s * (y * z - w * x),
        ],
        [
            s * (x * z - w * y),
            s * (y * z + w * x),
            1.0 - s * (x * x + y * y),
        ],
    ]
}

fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    m.map(|row| dot(row, v))
}

/// Every control point's [`Prepared`] part.
fn prepare(controls: Controls<'_>, nodes: &[f32]) -> Vec<Prepared> {
    (0..controls.positions.len())
        .map(|c| {
            let node = &nodes[c * NODE_OUTPUT..(c + 1) * NODE_OUTPUT];
            let p = wide(controls.positions[c]);
            let t = &node[TRANSLATION];
            let r2 = (2.0 * f64::from(controls.log_radii[c])).exp();
            Prepared {
                p,
                r2,
                two_r2: 2.0 * r2,
                a: 1.0 / (1.0 + (-f64::from(controls.weight_logits[c])).exp()),
                pt: std::array::from_fn(|i| p[i] + f64::from(t[i])),
                rot: local_quaternion(node).map(matrix),
            }
        })
        .collect()
}

/// The shares of a Gaussian's neighbours and the sum of their unnormalised weights.
fn shares(x: [f64; 3], index: &[u32], prepared: &[Prepared], out: &mut [Share]) -> f64 {
    let mut total = 0.0;
    for (share, &c) in out.iter_mut().zip(index) {
        let c = c as usize;
        let pc = &prepared[c];
        let v = sub(x, pc.p);
        let d2 = dot(v, v);
        // d² = 0 is weight 1 whatever the radius (0/0 when the radius underflows too).
        let e = if d2 == 0.0 {
            1.0
        } else {
            (-d2 / pc.two_r2).exp()
        };
        let raw = e * pc.a + WEIGHT_EPS;
        total += raw;
        *share = Share {
            c,
            v,
            d2,
            r2: pc.r2,
            e,
            a: pc.a,
            raw,
        };
    }
    total
}

/// A control point's blended target `R_c (x − p_c) + p_c + T_c`.
fn target(share: &Share, pc: &Prepared) -> [f64; 3] {
    let rv = pc.rot.as_ref().map_or(share.v, |m| mat_vec(m, share.v));
    std::array::from_fn(|i| rv[i] + pc.pt[i])
}

/// Adds one neighbour's part of a Gaussian's row sums: `w` times its target, rotation
/// residual `Q` and scale residual `S`.
fn blend(acc: &mut [f64; ROW], w: f64, y: [f64; 3], node: &[f32]) {
    for j in 0..3 {
        acc[j] += w * y[j];
    }
    for (a, &q) in acc[3..7].iter_mut().zip(&node[ROTATION]) {
        *a += w * f64::from(q);
    }
    for (a, &d) in acc[7..10].iter_mut().zip(&node[SCALE]) {
        *a += w * f64::from(d);
    }
}

/// The finished row of a Gaussian at `x`: the blend minus `x` on the position, in f32.
fn finish_row(mut acc: [f64; ROW], x: [f64; 3], row: &mut [f32]) {
    for j in 0..3 {
        acc[j] -= x[j];
    }
    for (o, a) in row.iter_mut().zip(acc) {
        *o = a as f32;
    }
}

/// The part of [`blend`]'s gradient that is linear in `w`: `w g` added to the neighbour's
/// translation, rotation-residual and scale-residual outputs `dn`; returns `g · (y, Q, S)`,
/// what the normalised weight's gradient needs.
fn add_blend_terms(dn: &mut [f64], g: &[f32], w: f64, y: [f64; 3], node: &[f32]) -> f64 {
    let mut h = 0.0;
    for c in TRANSLATION {
        h += f64::from(g[c]) * y[c];
        dn[c] += w * f64::from(g[c]);
    }
    for c in ROTATION.chain(SCALE) {
        h += f64::from(g[c]) * f64::from(node[c]);
        dn[c] += w * f64::from(g[c]);
    }
    h
}

/// The skinned rows (N × [`ROW`]) of the Gaussians at `means`, with their neighbours `nb`, the
/// control points' shape `controls` and their network outputs `nodes` (M × [`NODE_OUTPUT`]),
/// into `out` (whatever it held). [`reference::skin_into`] is its plain twin.
///
/// # Panics
/// When the sizes disagree (`nb` not of `means`' rows, `nodes` not of `controls`').
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
    let prepared = prepare(controls, nodes);
    out.clear();
    out.resize(means.len() * ROW, 0.0);
    out.par_chunks_mut(ROW)
        .zip(means.par_iter())
        .enumerate()
        .with_min_len(ROWS_PER_TASK)
        .for_each_init(
            || vec![Share::default(); k],
            |sh, (i, (row, &x))| {
                let x = wide(x);
                let total = shares(x, &nb.index[i * k..(i + 1) * k], &prepared, sh);
                let mut acc = [0f64; ROW];
                for s in sh.iter() {
                    let w = s.raw / total;
                    let node = &nodes[s.c * NODE_OUTPUT..(s.c + 1) * NODE_OUTPUT];
                    blend(&mut acc, w, target(s, &prepared[s.c]), node);
                }
                finish_row(acc, x, row);
            },
        );
}

/// Per-task sums of [`skin_backward`], in f64.
struct Sums {
    nodes: Vec<f64>,
    positions: Vec<f64>,
    log_radii: Vec<f64>,
    weight_logits: Vec<f64>,
    /// `Σ w g_x (x − p)ᵀ` per control point (M × 9, row-major): what the local rotation's
    /// gradient needs from the Gaussians, chained to the quaternion once per control point.
    outer: Vec<f64>,
}

impl Sums {
    fn zeros(m: usize) -> Self {
        Self {
            nodes: vec![0.0; m * NODE_OUTPUT],
            positions: vec![0.0; m * 3],
            log_radii: vec![0.0; m],
            weight_logits: vec![0.0; m],
            outer: vec![0.0; m * 9],
        }
    }

    fn add(&mut self, other: &Self) {
        let pairs = [
            (&mut self.nodes, &other.nodes),
            (&mut self.positions, &other.positions),
            (&mut self.log_radii, &other.log_radii),
            (&mut self.weight_logits, &other.weight_logits),
            (&mut self.outer, &other.outer),
        ];
        for (a, b) in pairs {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
    }

    /// Through one Gaussian's normalised weights to the radii, weight logits and positions of
    /// its neighbours `sh`, given `h_c` (dL/d(the neighbour's blended row) · its row), their
    /// weighted mean and the sum of the unnormalised weights.
    fn add_weight_terms(&mut self, sh: &[Share], h: &[f64], mean_h: f64, total: f64) {
        for (s, hs) in sh.iter().zip(h) {
            let d_raw = (hs - mean_h) / total;
            if s.e == 0.0 || d_raw == 0.0 {
                continue;
            }
            let ea = s.e * s.a;
            self.weight_logits[s.c] += d_raw * ea * (1.0 - s.a);
            if s.d2 > 0.0 {
                self.log_radii[s.c] += d_raw * ea * s.d2 / s.r2;
                // ∂raw/∂d² = −e a / (2 r²), ∂d²/∂p = −2 (x − p).
                let dd2 = -d_raw * ea / (2.0 * s.r2);
                for c in 0..3 {
                    self.positions[s.c * 3 + c] += dd2 * -2.0 * s.v[c];
                }
            }
        }
    }

    fn narrow(self) -> SkinGrads {
        let narrow = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
        SkinGrads {
            nodes: narrow(self.nodes),
            positions: narrow(self.positions),
            log_radii: narrow(self.log_radii),
            weight_logits: narrow(self.weight_logits),
        }
    }
}

/// The gradient of [`skin_into`]'s rows: from dL/d(rows) (`d_rows`, N × [`ROW`]) to the network
/// outputs and the control points' positions, log radii and weight logits.
/// [`reference::skin_backward`] is its plain twin.
///
/// The rigid part `R_c (x − p_c) + p_c + T_c` is linear in what the Gaussians contribute, so
/// they only add `Σ w g_x` (the translation's gradient) and `Σ w g_x (x − p_c)ᵀ` per control
/// point; the local quaternion's gradient and the position's `(I − R_cᵀ) Σ w g_x` are formed
/// from these sums once per control point. The Gaussians' sums are made in tasks of a fixed
/// number of rows and added in task order, so the result does not depend on the number of
/// threads.
///
/// # Panics
/// When the sizes disagree, as [`skin_into`].
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
    let prepared = prepare(controls, nodes);
    let tasks: Vec<Sums> = means
        .par_chunks(ROWS_PER_TASK)
        .enumerate()
        .map(|(t, chunk)| {
            let mut sums = Sums::zeros(m);
            let mut sh = vec![Share::default(); k];
            let mut h = vec![0f64; k];
            for (j, &x) in chunk.iter().enumerate() {
                let i = t * ROWS_PER_TASK + j;
                let g = &d_rows[i * ROW..(i + 1) * ROW];
                if g.iter().all(|&v| v == 0.0) {
                    continue;
                }
                let gx = [g[0], g[1], g[2]].map(f64::from);
                let total = shares(wide(x), &nb.index[i * k..(i + 1) * k], &prepared, &mut sh);
                let mut mean_h = 0.0;
                for (s, hs) in sh.iter().zip(&mut h) {
                    let w = s.raw / total;
                    let pc = &prepared[s.c];
                    let node = &nodes[s.c * NODE_OUTPUT..(s.c + 1) * NODE_OUTPUT];
                    let dn = &mut sums.nodes[s.c * NODE_OUTPUT..(s.c + 1) * NODE_OUTPUT];
                    *hs = add_blend_terms(dn, g, w, target(s, pc), node);
                    if pc.rot.is_some() {
                        let outer = &mut sums.outer[s.c * 9..(s.c + 1) * 9];
                        for r in 0..3 {
                            for c in 0..3 {
                                outer[r * 3 + c] += w * gx[r] * s.v[c];
                            }
                        }
                    }
                    mean_h += w * *hs;
                }
                sums.add_weight_terms(&sh, &h, mean_h, total);
            }
            sums
        })
        .collect();
    let mut total = Sums::zeros(m);
    for t in &tasks {
        total.add(t);
    }
    // The rigid part's gradient, once per control point: to the local quaternion
    // (`Σ_j ∂(G_{·j} · R e_j)/∂q` with G = the outer sums) and to the position.
    for (c, pc) in prepared.iter().enumerate() {
        let node = &nodes[c * NODE_OUTPUT..(c + 1) * NODE_OUTPUT];
        let (Some(q), Some(_)) = (local_quaternion(node), pc.rot) else {
            continue;
        };
        let o = &total.outer[c * 9..(c + 1) * 9];
        let mut dq = [0f64; 4];
        for j in 0..3 {
            let mut e = [0.0; 3];
            e[j] = 1.0;
            let column = [o[j], o[3 + j], o[6 + j]];
            for (d, v) in dq.iter_mut().zip(rotate_grad_q(q, e, column)) {
                *d += v;
            }
        }
        let dn = &mut total.nodes[c * NODE_OUTPUT..(c + 1) * NODE_OUTPUT];
        for (d, v) in dn[LOCAL].iter_mut().zip(dq) {
            *d += v;
        }
        let gy = [dn[0], dn[1], dn[2]];
        let back = rotate_back(q, gy);
        for i in 0..3 {
            total.positions[c * 3 + i] += gy[i] - back[i];
        }
    }
    total.narrow()
}
