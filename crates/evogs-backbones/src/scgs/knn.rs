//! The K nearest control points of every Gaussian, in canonical space: a k-d tree from `kiddo`
//! over the control points ([`nearest`]), the brute-force search it is tested against
//! ([`nearest_brute`]), and a cache that searches a moving Gaussian again only when its K
//! nearest may have changed ([`NeighbourCache`]; exact, not approximate).
//!
//! Fewer control points than K give every Gaussian all of them. Among equally distant control
//! points the tree may pick any; the distances it returns are the exact ones either way.

use std::num::NonZero;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use crate::error::BackboneError;

/// Gaussians per parallel query task.
const QUERIES_PER_TASK: usize = 2048;

/// The nearest control points of each of `rows` points: `k` per row, nearest first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Neighbours {
    /// Neighbours per row (the smaller of the K asked for and the control points).
    pub k: usize,
    /// Control-point indices, `rows × k`.
    pub index: Vec<u32>,
    /// Squared distances, `rows × k`, non-decreasing within a row.
    pub dist2: Vec<f32>,
}

impl Neighbours {
    /// Rows.
    pub fn rows(&self) -> usize {
        self.index.len().checked_div(self.k).unwrap_or(0)
    }
}

/// Checks that every coordinate of `points` is finite (a k-d tree cannot order NaN).
fn check_finite(what: &str, points: &[[f32; 3]]) -> Result<(), BackboneError> {
    match points.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
        Some(i) => Err(BackboneError::config(
            "scgs",
            format!("{what}: row {i} has a non-finite coordinate"),
        )),
        None => Ok(()),
    }
}

/// The `k` nearest of `controls` to every point of `queries`, through a k-d tree.
pub fn nearest(
    controls: &[[f32; 3]],
    queries: &[[f32; 3]],
    k: usize,
) -> Result<Neighbours, BackboneError> {
    let k = checked_k(controls, k)?;
    check_finite("control points", controls)?;
    check_finite("Gaussian means", queries)?;
    let tree: ImmutableKdTree<f32, 3> = ImmutableKdTree::new_from_slice(controls)
        .map_err(|e| BackboneError::config("scgs", format!("control-point tree: {e:?}")))?;
    let want = NonZero::new(k).expect("k is at least 1");
    let mut out = Neighbours {
        k,
        index: vec![0; queries.len() * k],
        dist2: vec![0.0; queries.len() * k],
    };
    out.index
        .par_chunks_mut(QUERIES_PER_TASK * k)
        .zip(out.dist2.par_chunks_mut(QUERIES_PER_TASK * k))
        .zip(queries.par_chunks(QUERIES_PER_TASK))
        .for_each(|((index, dist2), queries)| {
            for (j, q) in queries.iter().enumerate() {
                let found = tree
                    .query(q)
                    .nearest_n::<SquaredEuclidean<f32>>(want)
                    .execute();
                for (s, item) in found.iter().enumerate() {
                    index[j * k + s] = item.item;
                    // The distance from the point itself (the tree's may round differently).
                    dist2[j * k + s] = dist2_between(q, &controls[item.item as usize]);
                }
            }
        });
    Ok(out)
}

/// The K nearest control points of Gaussians that move a little between searches: a row is
/// searched again only when its Gaussian has moved far enough that its K nearest may have
/// changed, so the result is always the exact K nearest (module docs).
///
/// At a row's search it keeps the Gaussian's position `x₀`, the distance `d_K` to its K-th
/// nearest and `d_{K+1}` to the next one. Moved to `x`, `|x − x₀| = δ`, every distance changes by
/// at most δ, so the same K stay the nearest while `d_K + δ < d_{K+1} − δ`: the row is searched
/// again when `δ ≥ (d_{K+1} − d_K) / 2` (less a rounding margin). Each row's K are then put in the
/// order of their distance from `x` (ties by index), so the result does not depend on which rows
/// were searched: a resumed run, whose first search is of every row, gets the same rows as an
/// uninterrupted one. A change of the control points, of K or of the number of Gaussians searches
/// every row.
#[derive(Clone, Debug, Default)]
pub struct NeighbourCache {
    controls: Vec<[f32; 3]>,
    k: usize,
    /// Per row: the Gaussian's position at its last search.
    searched_at: Vec<[f32; 3]>,
    /// Per row: how far it may move before its K nearest may change.
    margin: Vec<f64>,
    neighbours: Neighbours,
    /// Rows searched by the last update.
    searched: usize,
}

impl NeighbourCache {
    /// The K nearest of `controls` to every point of `means`, searching again only the rows
    /// that need it.
    pub fn update(
        &mut self,
        controls: &[[f32; 3]],
        means: &[[f32; 3]],
        k: usize,
    ) -> Result<&Neighbours, BackboneError> {
        let k = checked_k(controls, k)?;
        check_finite("Gaussian means", means)?;
        let all = self.k != k || self.controls != controls || self.searched_at.len() != means.len();
        let stale: Vec<usize> = if all {
            (0..means.len()).collect()
        } else {
            (0..means.len())
                .into_par_iter()
                .with_min_len(QUERIES_PER_TASK)
                .filter(|&i| {
                    let d = distance(&means[i], &self.searched_at[i]);
                    // Searched again unless it moved less than its margin (so a NaN, which
                    // finite inputs cannot make, would search again too).
                    d.partial_cmp(&self.margin[i]) != Some(std::cmp::Ordering::Less)
                })
                .collect()
        };
        if all {
            self.controls.clear();
            self.controls.extend_from_slice(controls);
            self.k = k;
            self.searched_at = vec![[0.0; 3]; means.len()];
            self.margin = vec![0.0; means.len()];
            self.neighbours = Neighbours {
                k,
                index: vec![0; means.len() * k],
                dist2: vec![0.0; means.len() * k],
            };
        }
        self.searched = stale.len();
        if !stale.is_empty() {
            // One more than K, for the margin (when there is one more).
            let wide = (k + 1).min(controls.len());
            let queries: Vec<[f32; 3]> = stale.iter().map(|&i| means[i]).collect();
            let found = nearest(controls, &queries, wide)?;
            for (j, &i) in stale.iter().enumerate() {
                let row = &found.index[j * wide..(j + 1) * wide];
                self.neighbours.index[i * k..(i + 1) * k].copy_from_slice(&row[..k]);
                self.searched_at[i] = means[i];
                self.margin[i] = if wide > k {
                    let near = distance(&means[i], &controls[row[k - 1] as usize]);
                    let next = distance(&means[i], &controls[row[k] as usize]);
                    // Less a margin for the rounding of the tree's f32 distances.
                    (next - near) / 2.0 - 1e-5 * (1.0 + next)
                } else {
                    f64::INFINITY
                };
            }
        }
        let nb = &mut self.neighbours;
        nb.index
            .par_chunks_mut(k)
            .zip(nb.dist2.par_chunks_mut(k))
            .zip(means.par_iter())
            .with_min_len(QUERIES_PER_TASK)
            .for_each(|((index, dist2), x)| order_row(controls, x, index, dist2));
        Ok(&self.neighbours)
    }

    /// Rows the last [`NeighbourCache::update`] searched again.
    pub fn searched(&self) -> usize {
        self.searched
    }

    /// The neighbours of the last update.
    pub fn neighbours(&self) -> &Neighbours {
        &self.neighbours
    }
}

/// Puts a row's control points in the order of their squared distance from `x` (ties by
/// index), writing the distances.
fn order_row(controls: &[[f32; 3]], x: &[f32; 3], index: &mut [u32], dist2: &mut [f32]) {
    for (d, &c) in dist2.iter_mut().zip(index.iter()) {
        *d = dist2_between(x, &controls[c as usize]);
    }
    // Insertion sort: K is small.
    for a in 1..index.len() {
        let mut b = a;
        while b > 0 && (dist2[b - 1], index[b - 1]) > (dist2[b], index[b]) {
            index.swap(b - 1, b);
            dist2.swap(b - 1, b);
            b -= 1;
        }
    }
}

/// |a − b| in f64.
fn distance(a: &[f32; 3], b: &[f32; 3]) -> f64 {
    (0..3)
        .map(|c| (f64::from(a[c]) - f64::from(b[c])).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// [`nearest`] by comparing every pair (the reference): ties go to the lower index.
pub fn nearest_brute(
    controls: &[[f32; 3]],
    queries: &[[f32; 3]],
    k: usize,
) -> Result<Neighbours, BackboneError> {
    let k = checked_k(controls, k)?;
    let mut out = Neighbours {
        k,
        ..Neighbours::default()
    };
    for q in queries {
        let mut all: Vec<(f32, u32)> = controls
            .iter()
            .enumerate()
            .map(|(i, c)| (dist2_between(q, c), i as u32))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(d, i) in &all[..k] {
            out.index.push(i);
            out.dist2.push(d);
        }
    }
    Ok(out)
}

/// The neighbours per row for `k` asked of `controls`: `min(k, controls)`, refusing none.
fn checked_k(controls: &[[f32; 3]], k: usize) -> Result<usize, BackboneError> {
    if controls.is_empty() || k == 0 {
        return Err(BackboneError::config(
            "scgs",
            format!(
                "nearest control points: {k} asked of {} control points",
                controls.len()
            ),
        ));
    }
    if u32::try_from(controls.len()).is_err() {
        return Err(BackboneError::config(
            "scgs",
            "more than 2^32 control points",
        ));
    }
    Ok(k.min(controls.len()))
}

/// |a − b|², summed in the same order everywhere.
pub fn dist2_between(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The tree's distances agree with brute force's, and so do its indices wherever the
    /// distances are not tied.
    fn agree(controls: &[[f32; 3]], queries: &[[f32; 3]], k: usize) {
        let a = nearest(controls, queries, k).unwrap();
        let b = nearest_brute(controls, queries, k).unwrap();
        assert_eq!(a.k, b.k);
        assert_eq!(a.dist2, b.dist2);
        for (r, (ia, ib)) in a.index.chunks(a.k).zip(b.index.chunks(b.k)).enumerate() {
            for s in 0..a.k {
                let d = b.dist2[r * b.k + s];
                let at_d = controls
                    .iter()
                    .filter(|c| dist2_between(&queries[r], c) == d)
                    .count();
                if at_d == 1 {
                    assert_eq!(ia[s], ib[s], "row {r} slot {s}");
                }
            }
        }
    }

    #[test]
    fn ties_duplicates_and_fewer_controls_than_k() {
        // A lattice: many ties at equal distances.
        let lattice: Vec<[f32; 3]> = (0..27)
            .map(|i| [(i % 3) as f32, ((i / 3) % 3) as f32, (i / 9) as f32])
            .collect();
        let queries = [
            [1.0, 1.0, 1.0],
            [0.5, 0.5, 0.5],
            [0.0, 0.0, 0.0],
            [9.0, -3.0, 2.0],
        ];
        agree(&lattice, &queries, 3);
        agree(&lattice, &queries, 8);
        // Duplicates: the same point 40 times (more than a leaf holds) and one other.
        let mut dup = vec![[0.25f32, 0.5, -1.0]; 40];
        dup.push([3.0, 3.0, 3.0]);
        let n = nearest(&dup, &[[0.25, 0.5, -1.0], [3.0, 3.0, 2.0]], 3).unwrap();
        assert_eq!(n.dist2[..3], [0.0; 3]);
        assert_eq!(n.index[3], 40);
        // Fewer control points than K: all of them, nearest first.
        let two = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let n = nearest(&two, &[[0.9, 0.0, 0.0]], 3).unwrap();
        assert_eq!((n.k, n.index.as_slice()), (2, [1u32, 0].as_slice()));
        // None, or a NaN, is refused.
        assert!(nearest(&[], &[[0.0; 3]], 3).is_err());
        let e = nearest(&two, &[[f32::NAN, 0.0, 0.0]], 3).unwrap_err();
        assert!(e.to_string().contains("Gaussian means: row 0"), "{e}");
    }

    /// The cache gives what a fresh search gives, with the rows in the order of distance, while
    /// the points move by small and large steps; small steps search few rows again.
    #[test]
    fn the_cache_answers_as_a_fresh_search() {
        let controls: Vec<[f32; 3]> = (0..64)
            .map(|i| {
                let f = i as f32;
                [(f * 0.73).sin(), (f * 1.31).cos(), (f * 0.37).sin()]
            })
            .collect();
        let mut means: Vec<[f32; 3]> = (0..500)
            .map(|i| {
                let f = i as f32;
                [(f * 0.11).cos(), (f * 0.53).sin(), (f * 0.29).cos()]
            })
            .collect();
        let mut cache = NeighbourCache::default();
        for step in 0..30 {
            let size = if step % 10 == 9 { 0.3 } else { 1e-3 };
            for (i, m) in means.iter_mut().enumerate() {
                let f = (i * 31 + step * 7) as f32;
                m[0] += size * f.sin();
                m[1] += size * f.cos();
            }
            let got = cache.update(&controls, &means, 3).unwrap().clone();
            let mut fresh = nearest_brute(&controls, &means, 3).unwrap();
            for ((index, dist2), x) in fresh
                .index
                .chunks_mut(3)
                .zip(fresh.dist2.chunks_mut(3))
                .zip(&means)
            {
                order_row(&controls, x, index, dist2);
            }
            assert_eq!(got, fresh, "step {step}");
            if step > 0 && size < 1e-2 {
                assert!(cache.searched() < means.len() / 4, "{}", cache.searched());
            }
        }
        // Other control points: every row again.
        let moved: Vec<[f32; 3]> = controls.iter().map(|c| [c[0] + 0.01, c[1], c[2]]).collect();
        cache.update(&moved, &means, 3).unwrap();
        assert_eq!(cache.searched(), means.len());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn the_tree_finds_what_brute_force_finds(
            controls in prop::collection::vec(prop::array::uniform3(-4i8..4), 1..80),
            queries in prop::collection::vec(prop::array::uniform3(-40i16..40), 0..40),
            k in 1usize..6,
        ) {
            // Coordinates on a coarse grid, so ties and duplicates are common.
            let controls: Vec<[f32; 3]> =
                controls.iter().map(|c| c.map(|v| f32::from(v) * 0.5)).collect();
            let queries: Vec<[f32; 3]> =
                queries.iter().map(|q| q.map(|v| f32::from(v) * 0.1)).collect();
            agree(&controls, &queries, k);
        }
    }
}
