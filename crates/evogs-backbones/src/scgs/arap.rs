//! SC-GS's as-rigid-as-possible loss on the control points' trajectories, and its gradient.
//!
//! SC-GS (`utils/deform_utils.py`, `cal_arap_error`; `ControlNodeWarp.arap_loss` in
//! `utils/time_utils.py`) compares the control points at two nearby times `τ0`, `τ1`: each point
//! `i` and its graph neighbours `j` (the [`ArapGraph::NEIGHBOURS`] nearest at `τ0`; beyond the
//! [`ArapGraph::ALWAYS`] nearest only those closer than [`ArapGraph::RADIUS`]) should move as one
//! rigid piece, `e_ij(τ1) ≈ R_i e_ij(τ0)` with `e_ij = P_j − P_i`, where `R_i` is the rotation
//! that fits the edges best (Procrustes, by an SVD; held constant in the gradient, as SC-GS's
//! `torch.no_grad()` fit). The loss is the sum `Σ_i Σ_j |e_ij(τ1) − R_i e_ij(τ0)|²` (a sum, as
//! SC-GS's; its weight is the backbone's `arap_weight`).

use nalgebra::{Matrix3, Vector3};

use super::knn;
use crate::error::BackboneError;

/// The neighbour graph of SC-GS's ARAP loss.
#[derive(Clone, Copy, Debug)]
pub struct ArapGraph;

impl ArapGraph {
    /// Neighbours per point (SC-GS: `K=10` in `arap_loss`, the point itself excluded).
    pub const NEIGHBOURS: usize = 10;
    /// The nearest neighbours always kept (SC-GS: `least_edge_num=3`).
    pub const ALWAYS: usize = 3;
    /// Farther neighbours are kept within this distance (SC-GS: `radius=0.1`, scene units; the
    /// D-NeRF scenes' units).
    pub const RADIUS: f32 = 0.1;
}

/// The loss and its gradient with respect to the points at the two times.
#[derive(Clone, Debug, PartialEq)]
pub struct Arap {
    /// `Σ_i Σ_j |e_ij(τ1) − R_i e_ij(τ0)|²`.
    pub loss: f64,
    /// dL/dP(τ0), M × 3.
    pub d_first: Vec<f32>,
    /// dL/dP(τ1), M × 3.
    pub d_second: Vec<f32>,
}

/// The ARAP loss of points `first` (at τ0) and `second` (at τ1), M × 3 each, on the graph of
/// `first` ([`graph`]).
pub fn arap(first: &[[f32; 3]], second: &[[f32; 3]]) -> Result<Arap, BackboneError> {
    Ok(arap_on(&graph(first)?, first, second))
}

/// The edges of SC-GS's ARAP graph of `points`: per point, its neighbours (ascending distance;
/// the point itself, or a duplicate standing in for it, left out).
pub fn graph(points: &[[f32; 3]]) -> Result<Vec<Vec<usize>>, BackboneError> {
    let m = points.len();
    if m < 2 {
        return Ok(vec![Vec::new(); m]);
    }
    let nb = knn::nearest(points, points, ArapGraph::NEIGHBOURS + 1)?;
    Ok((0..m)
        .map(|i| {
            let row = &nb.index[i * nb.k..(i + 1) * nb.k];
            let d2 = &nb.dist2[i * nb.k..(i + 1) * nb.k];
            let own = row
                .iter()
                .position(|&j| j as usize == i)
                .unwrap_or(nb.k - 1);
            row.iter()
                .zip(d2)
                .enumerate()
                .filter(|&(s, _)| s != own)
                .map(|(_, p)| p)
                .take(ArapGraph::NEIGHBOURS)
                .enumerate()
                .filter(|&(rank, (_, &d))| {
                    rank < ArapGraph::ALWAYS || d < ArapGraph::RADIUS * ArapGraph::RADIUS
                })
                .map(|(_, (&j, _))| j as usize)
                .collect()
        })
        .collect())
}

/// The ARAP loss of `first` and `second` on the edges of `graph` (held: the gradient is the one
/// of a fixed graph, as SC-GS's, whose graph is a `no_grad` k-nearest search).
///
/// # Panics
/// When the sizes disagree or an edge names a point out of range.
pub fn arap_on(graph: &[Vec<usize>], first: &[[f32; 3]], second: &[[f32; 3]]) -> Arap {
    let m = first.len();
    assert_eq!(second.len(), m, "the same points at both times");
    assert_eq!(graph.len(), m, "a graph of the points");
    let at = |p: &[[f32; 3]], i: usize| Vector3::from(p[i].map(f64::from));
    let mut loss = 0.0;
    let mut d_first = vec![Vector3::<f64>::zeros(); m];
    let mut d_second = vec![Vector3::<f64>::zeros(); m];
    let mut edges: Vec<(usize, Vector3<f64>, Vector3<f64>)> = Vec::new();
    for (i, neighbours) in graph.iter().enumerate() {
        edges.clear();
        edges.extend(neighbours.iter().map(|&j| {
            (
                j,
                at(first, j) - at(first, i),
                at(second, j) - at(second, i),
            )
        }));
        let rotation = fit_rotation(edges.iter().map(|(_, e0, e1)| (*e0, *e1)));
        for (j, e0, e1) in &edges {
            let r = e1 - rotation * e0;
            loss += r.norm_squared();
            let g0 = -2.0 * rotation.transpose() * r;
            let g1 = 2.0 * r;
            d_first[*j] += g0;
            d_first[i] -= g0;
            d_second[*j] += g1;
            d_second[i] -= g1;
        }
    }
    let flat = |v: Vec<Vector3<f64>>| {
        v.iter()
            .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect()
    };
    Arap {
        loss,
        d_first: flat(d_first),
        d_second: flat(d_second),
    }
}

/// The rotation `R` minimising `Σ |e1 − R e0|²` over the pairs `(e0, e1)` (Kabsch: the SVD of
/// `Σ e1 e0ᵀ`, with the sign that keeps `det R = 1`); the identity when the pairs fix none.
pub fn fit_rotation(pairs: impl Iterator<Item = (Vector3<f64>, Vector3<f64>)>) -> Matrix3<f64> {
    let s: Matrix3<f64> = pairs.map(|(e0, e1)| e1 * e0.transpose()).sum();
    if s.iter().all(|v| *v == 0.0) || s.iter().any(|v| !v.is_finite()) {
        return Matrix3::identity();
    }
    let svd = s.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let mut r = u * v_t;
    if r.determinant() < 0.0 {
        // Flip the axis of the smallest singular value (nalgebra sorts them in decreasing order).
        let mut u = u;
        u.column_mut(2).neg_mut();
        r = u * v_t;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn cloud(m: usize) -> Vec<[f32; 3]> {
        (0..m)
            .map(|i| {
                let f = i as f32;
                [
                    (f * 0.37).sin() * 0.3,
                    (f * 0.71).cos() * 0.3,
                    (f * 0.13).sin() * 0.3,
                ]
            })
            .collect()
    }

    /// A rigid motion (rotation and translation) costs nothing; the fitted rotation is the
    /// motion's.
    #[test]
    fn a_rigid_motion_is_free() {
        let first = cloud(40);
        let rot = Rotation3::from_euler_angles(0.3, -0.2, 0.7);
        let second: Vec<[f32; 3]> = first
            .iter()
            .map(|p| {
                let q = rot * Vector3::from(p.map(f64::from)) + Vector3::new(0.5, -1.0, 2.0);
                [q.x as f32, q.y as f32, q.z as f32]
            })
            .collect();
        let a = arap(&first, &second).unwrap();
        assert!(a.loss < 1e-10, "{}", a.loss);
        let pairs = first.windows(2).zip(second.windows(2)).map(|(f, s)| {
            let e = |p: &[[f32; 3]]| {
                Vector3::from(p[1].map(f64::from)) - Vector3::from(p[0].map(f64::from))
            };
            (e(f), e(s))
        });
        let r = fit_rotation(pairs);
        assert!((r - rot.matrix()).norm() < 1e-5, "{r}");
    }

    /// The gradient against f64 central differences with the graph held (the fitted rotations
    /// are refitted: at the optimal fit their own change costs nothing to first order).
    #[test]
    fn gradient_matches_finite_differences() {
        let first = cloud(24);
        let second: Vec<[f32; 3]> = first
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let f = i as f32;
                [
                    p[0] + 0.02 * f.sin(),
                    p[1] * 1.1,
                    p[2] + 0.01 * (f * 2.0).cos(),
                ]
            })
            .collect();
        let graph = graph(&first).unwrap();
        let a = arap_on(&graph, &first, &second);
        assert!(a.loss > 1e-6);
        let h = 1e-3f32;
        for (which, grad) in [(0, &a.d_first), (1, &a.d_second)] {
            for idx in [0, 5, 17, 40, 71] {
                let moved = |delta: f32| {
                    let (mut f, mut s) = (first.clone(), second.clone());
                    let p = if which == 0 { &mut f } else { &mut s };
                    p[idx / 3][idx % 3] += delta;
                    arap_on(&graph, &f, &s).loss
                };
                let fd = (moved(h) - moved(-h)) / (2.0 * f64::from(h));
                let g = f64::from(grad[idx]);
                assert!(
                    (fd - g).abs() <= 2e-3 * g.abs().max(1e-2),
                    "time {which} value {idx}: fd {fd} vs {g}"
                );
            }
        }
    }

    /// One point, two coincident points, and a reflection-only fit give finite results.
    #[test]
    fn degenerate_graphs_stay_finite() {
        assert_eq!(arap(&[[0.0; 3]], &[[1.0; 3]]).unwrap().loss, 0.0);
        let a = arap(&[[0.0; 3]; 2], &[[0.0, 0.0, 0.1], [0.0; 3]]).unwrap();
        assert!(a.loss.is_finite() && a.d_first.iter().all(|v| v.is_finite()));
        // Points on a line mirrored: the fit stays a rotation.
        let line = [[0.0f32, 0.0, 0.0], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0]];
        let mirrored = line.map(|p| [-p[0], p[1], p[2]]);
        let a = arap(&line, &mirrored).unwrap();
        assert!(a.loss.is_finite(), "{}", a.loss);
    }
}
