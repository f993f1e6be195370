//! Deterministic parallel reductions of parameter gradients.
//!
//! Row blocks are processed in parallel, and each parallel task accumulates its blocks' parameter
//! gradients into its own vector. A work-stealing fold would group blocks differently from run to
//! run, so the f32 sums would round differently and training would not be reproducible for a
//! seed. Here the grouping is fixed: the blocks are cut into at most [`REDUCE_GROUPS`] contiguous
//! groups (a constant, not the thread count), each group is folded in block order, and the
//! groups' results are merged in group order. The result is bit-identical for any scheduling and
//! any number of threads.

use rayon::prelude::*;

/// How many contiguous groups a reduction cuts its blocks into: enough to keep a few cores busy,
/// few enough that the per-group gradient vectors stay cheap to allocate and merge.
pub(crate) const REDUCE_GROUPS: usize = 8;

/// Folds `items` with their index in at most [`REDUCE_GROUPS`] contiguous groups, in parallel,
/// each group sequentially from `init()`, then merges the groups' results in order.
pub(crate) fn fold_in_order<T, A, I, F, M>(items: Vec<T>, init: I, fold: F, merge: M) -> A
where
    T: Send,
    A: Send,
    I: Fn() -> A + Sync + Send,
    F: Fn(A, (usize, T)) -> A + Sync + Send,
    M: Fn(A, A) -> A,
{
    let group = items.len().div_ceil(REDUCE_GROUPS).max(1);
    let parts: Vec<A> = items
        .into_par_iter()
        .enumerate()
        .chunks(group)
        .map(|chunk| chunk.into_iter().fold(init(), &fold))
        .collect();
    parts.into_iter().reduce(merge).unwrap_or_else(init)
}

/// Values per parallel task of [`add_into`].
const ADD_CHUNK: usize = 1 << 14;

/// Adds `b` into `a` element by element (in parallel chunks: each element's sum is the same
/// for any split).
pub(crate) fn add_into(mut a: Vec<f32>, b: Vec<f32>) -> Vec<f32> {
    a.par_chunks_mut(ADD_CHUNK)
        .zip(b.par_chunks(ADD_CHUNK))
        .for_each(|(a, b)| a.iter_mut().zip(b).for_each(|(x, y)| *x += y));
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_are_bit_identical_for_any_thread_count() {
        // Values whose f32 sum depends on the order of addition.
        let items: Vec<f32> = (0..1000)
            .map(|i| ((i * 7919) % 1009) as f32 * 1.37e-3 + if i % 3 == 0 { 1e4 } else { 0.0 })
            .collect();
        let sum_with = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                fold_in_order(items.clone(), || 0.0f32, |a, (_, v)| a + v, |a, b| a + b)
            })
        };
        let one = sum_with(1);
        for threads in [2, 3, 5] {
            for _ in 0..5 {
                assert_eq!(sum_with(threads).to_bits(), one.to_bits());
            }
        }
        let indices = fold_in_order(
            vec![(); 37],
            Vec::new,
            |mut a, (i, ())| {
                a.push(i);
                a
            },
            |mut a, b| {
                a.extend(b);
                a
            },
        );
        assert_eq!(indices, (0..37).collect::<Vec<_>>());
        assert_eq!(
            fold_in_order(
                Vec::<f32>::new(),
                || 0.0f32,
                |a, (_, v)| a + v,
                |a, b| a + b
            ),
            0.0
        );
    }
}
