//! Farthest-point sampling: `m` of a cloud's points spread as evenly as the cloud allows, the
//! way SC-GS picks its control points (`utils/time_utils.py`, `farthest_point_sample`).
//!
//! It starts at a seeded index (SC-GS: a random one) and adds, one at a time, the point farthest
//! from those picked (ties to the lower index). When `m` exceeds the cloud, every point is
//! picked once and the rest repeat the cloud from its start (coincident control points: their
//! weights then split a Gaussian's pull between them, which the skinning allows).

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Indices of `m` points of `points` (of any dimension `D`: 3 for positions, more for
/// trajectories) picked by farthest-point sampling from a seeded start; empty for an empty
/// cloud.
pub fn farthest_points<const D: usize>(points: &[[f32; D]], m: usize, seed: u64) -> Vec<usize> {
    let n = points.len();
    if n == 0 || m == 0 {
        return Vec::new();
    }
    let mut picked = Vec::with_capacity(m);
    let mut nearest = vec![f32::INFINITY; n];
    let mut next = ChaCha8Rng::seed_from_u64(seed).random_range(0..n);
    for _ in 0..m.min(n) {
        picked.push(next);
        let p = points[next];
        let mut best = (f32::NEG_INFINITY, 0);
        for (i, (q, d)) in points.iter().zip(&mut nearest).enumerate() {
            *d = d.min(dist2(&p, q));
            if *d > best.0 {
                best = (*d, i);
            }
        }
        next = best.1;
    }
    for i in 0..m.saturating_sub(n) {
        picked.push(i % n);
    }
    picked
}

/// Squared Euclidean distance, summed from the first coordinate on (for `D = 3` the same
/// value, bit for bit, as [`super::knn::dist2_between`]).
fn dist2<const D: usize>(a: &[f32; D], b: &[f32; D]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each pick is a point farthest from those before it (brute force), every point of a cloud
    /// is picked before any repeats, and a cloud smaller than `m` is taken whole and repeated.
    #[test]
    fn each_pick_is_the_farthest_and_small_clouds_repeat() {
        let mut cloud: Vec<[f32; 3]> = (0..125)
            .map(|i| [(i % 5) as f32, ((i / 5) % 5) as f32, (i / 25) as f32 * 0.7])
            .collect();
        cloud.rotate_left(37);
        let picked = farthest_points(&cloud, 20, 3);
        let d = |a: usize, b: usize| crate::scgs::knn::dist2_between(&cloud[a], &cloud[b]);
        for j in 1..picked.len() {
            let from_picked = |i: usize| {
                picked[..j]
                    .iter()
                    .map(|&p| d(i, p))
                    .fold(f32::INFINITY, f32::min)
            };
            let best = (0..cloud.len()).map(from_picked).fold(0.0, f32::max);
            assert_eq!(from_picked(picked[j]), best, "pick {j}");
        }
        let mut unique = picked.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), 20);
        let small = farthest_points(&cloud[..2], 5, 1);
        assert_eq!(&small[2..], [0, 1, 0]);
        assert!(farthest_points::<3>(&[], 4, 0).is_empty());
        assert_eq!(farthest_points(&cloud, 20, 3), picked, "seeded");
    }

    /// In more dimensions than three (trajectories): a cloud whose first three coordinates
    /// coincide is spread by its last three, exactly as the 3D cloud of those is.
    #[test]
    fn trajectories_are_spread_by_every_coordinate() {
        let last: Vec<[f32; 3]> = (0..40)
            .map(|i| {
                let i = i as f32;
                [(i * 0.37).sin(), (i * 1.3).cos() * 2.0, (i * 0.11).fract()]
            })
            .collect();
        let cloud: Vec<[f32; 6]> = last
            .iter()
            .map(|p| [0.5, 0.5, 0.5, p[0], p[1], p[2]])
            .collect();
        for seed in 0..5 {
            assert_eq!(
                farthest_points(&cloud, 12, seed),
                farthest_points(&last, 12, seed),
                "seed {seed}"
            );
        }
    }
}
