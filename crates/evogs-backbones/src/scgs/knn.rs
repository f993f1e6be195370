//! The K nearest control points of every Gaussian, in canonical space: a k-d tree from `kiddo`
//! over the control points ([`nearest`]) and the brute-force search it is tested against
//! ([`nearest_brute`]).
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
