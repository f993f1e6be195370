//! Tile binning: per 16×16 tile, the ids of the Gaussians whose extent touches it, in depth order
//! (camera z ascending, ties broken by index, so the order is total and deterministic).

use rayon::prelude::*;

/// Per-tile lists of drawn Gaussians in one flat array: tile `t` owns
/// `ids[offsets[t]..offsets[t + 1]]`, each entry the Gaussian's rank in depth order (Gaussian
/// `order[rank]`), so that a tile reads records stored in depth order front to back; and, per
/// Gaussian, where its entries went: Gaussian `i`'s entries are `ids[entry_from_pair[p]]` for `p`
/// in `pairs_of[i]..pairs_of[i + 1]`, in ascending tile order.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct TileLists {
    pub offsets: Vec<usize>,
    /// Depth ranks, tile by tile.
    pub ids: Vec<u32>,
    /// Gaussian index of each depth rank.
    pub order: Vec<u32>,
    /// Per Gaussian (by index), the start of its pairs in `entry_from_pair`; `n + 1` long.
    pub pairs_of: Vec<usize>,
    /// Per (Gaussian, tile) pair, Gaussian-major, its position in `ids`.
    pub entry_from_pair: Vec<u32>,
}

impl TileLists {
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.ids[self.offsets[t]..self.offsets[t + 1]]
    }

    /// Positions in `ids` of Gaussian `i`'s entries, in ascending tile order.
    pub fn entries_of(&self, i: usize) -> &[u32] {
        &self.entry_from_pair[self.pairs_of[i]..self.pairs_of[i + 1]]
    }
}

/// Gaussians per task when listing the tiles they touch (fixed, so the work split does not
/// depend on the thread count; the result never does).
const CHUNK: usize = 256;

/// Buffers [`bin_into`] reuses between calls (only their capacity matters).
#[derive(Clone, Debug, Default)]
pub(crate) struct BinScratch {
    /// Per chunk of [`CHUNK`] Gaussians, per Gaussian the count of tiles it touches, and those
    /// tiles.
    touched: Vec<(Vec<u32>, Vec<u32>)>,
    /// The tile of each (Gaussian, tile) pair, Gaussian-major.
    tile_of_pair: Vec<u32>,
    /// Depth-order sort keys.
    keys: Vec<u64>,
    /// The pair of each entry (the inverse of `entry_from_pair`, built first).
    pair_from_entry: Vec<u32>,
    /// Per tile, the next free position in `ids`.
    cursor: Vec<usize>,
}

/// Bins drawn Gaussians into tiles. `rects[i]` is Gaussian `i`'s inclusive tile rectangle
/// `[x0, y0, x1, y1]` (None when culled) and `depth[i]` its camera z (> 0 when drawn); within the
/// rectangle, only tiles `(tx, ty)` with `touches(i, tx, ty)` get the Gaussian.
#[cfg(test)]
pub(crate) fn bin(
    rects: &[Option<[u32; 4]>],
    depth: &[f32],
    tiles_x: u32,
    tiles_y: u32,
    touches: impl Fn(u32, u32, u32) -> bool + Sync,
) -> TileLists {
    let mut lists = TileLists::default();
    bin_into(
        rects,
        depth,
        tiles_x,
        tiles_y,
        tiles_where(tiles_x, touches),
        &mut lists,
        &mut BinScratch::default(),
    );
    lists
}

/// The `touched` argument of [`bin_into`] from a per-tile predicate `touches(i, tx, ty)`.
#[cfg(test)]
fn tiles_where(
    tiles_x: u32,
    touches: impl Fn(u32, u32, u32) -> bool + Sync,
) -> impl Fn(u32, [u32; 4], &mut Vec<u32>) + Sync {
    move |id, [x0, y0, x1, y1], touched| {
        for ty in y0..=y1 {
            for tx in x0..=x1 {
                if touches(id, tx, ty) {
                    touched.push(ty * tiles_x + tx);
                }
            }
        }
    }
}

/// [`bin`] into `lists`, reusing its buffers and `scratch`'s: the same lists, without fresh
/// allocations once the buffers are large enough. `tiles_of(i, rect, tiles)` pushes onto `tiles`
/// the index `ty · tiles_x + tx` of each tile of Gaussian `i`'s rectangle `rect` it touches, in
/// ascending order.
pub(crate) fn bin_into(
    rects: &[Option<[u32; 4]>],
    depth: &[f32],
    tiles_x: u32,
    tiles_y: u32,
    tiles_of: impl Fn(u32, [u32; 4], &mut Vec<u32>) + Sync,
    lists: &mut TileLists,
    scratch: &mut BinScratch,
) {
    let n = rects.len();
    let BinScratch {
        touched,
        tile_of_pair,
        keys,
        pair_from_entry,
        cursor,
    } = scratch;
    // The tiles each Gaussian touches, in row-major tile order, Gaussian by Gaussian.
    touched.resize_with(n.div_ceil(CHUNK), Default::default);
    touched
        .par_iter_mut()
        .zip(rects.par_chunks(CHUNK))
        .enumerate()
        .for_each(|(c, ((counts, tiles), rects))| {
            counts.clear();
            tiles.clear();
            for (k, rect) in rects.iter().enumerate() {
                let before = tiles.len();
                if let Some(rect) = *rect {
                    tiles_of((c * CHUNK + k) as u32, rect, tiles);
                }
                counts.push((tiles.len() - before) as u32);
            }
        });
    let pairs_of = &mut lists.pairs_of;
    pairs_of.clear();
    pairs_of.push(0usize);
    for (counts, _) in touched.iter() {
        for &k in counts {
            pairs_of.push(pairs_of.last().unwrap() + k as usize);
        }
    }
    tile_of_pair.clear();
    for (_, tiles) in touched.iter() {
        tile_of_pair.extend_from_slice(tiles);
    }

    // Depth order: z > 0 is finite and positive, so its bit pattern orders like the number;
    // ties are broken by index.
    keys.clear();
    keys.extend(
        rects
            .iter()
            .enumerate()
            .filter(|(_, r)| r.is_some())
            .map(|(i, _)| (u64::from(depth[i].to_bits()) << 32) | i as u64),
    );
    keys.par_sort_unstable();

    // A stable counting sort of the pairs by tile, visiting Gaussians in depth order.
    let n_tiles = tiles_x as usize * tiles_y as usize;
    let offsets = &mut lists.offsets;
    offsets.clear();
    offsets.resize(n_tiles + 1, 0);
    for &t in tile_of_pair.iter() {
        offsets[t as usize + 1] += 1;
    }
    for t in 0..n_tiles {
        offsets[t + 1] += offsets[t];
    }
    let (ids, entry_from_pair, order) =
        (&mut lists.ids, &mut lists.entry_from_pair, &mut lists.order);
    order.clear();
    order.extend(keys.iter().map(|&key| key as u32));
    // Every position of both arrays is written below.
    ids.resize(tile_of_pair.len(), 0);
    entry_from_pair.resize(tile_of_pair.len(), 0);
    pair_from_entry.resize(tile_of_pair.len(), 0);
    cursor.resize(n_tiles, 0);
    scatter(
        order,
        pairs_of,
        tile_of_pair,
        offsets,
        (ids, entry_from_pair),
        (pair_from_entry, cursor),
    );
}

/// The counting sort's scatter: visiting Gaussians in depth order, each of its pairs takes the
/// next free position of its tile's list (`ids[e] = rank`, `entry_from_pair[p] = e`).
///
/// In parallel without shared writes or allocations: the tiles are cut into `G` ranges of about
/// equal entry counts (each a contiguous part of `ids`); each range's task visits every Gaussian
/// in depth order and fills its own part of `ids` and of `pair_from_entry` (the pair of each
/// entry). Then `entry_from_pair`, the inverse, is cut into `G` ranges of pairs, each task
/// reading all of `pair_from_entry` and writing its own range. Every position has one value
/// whatever `G` is, so the lists do not depend on the thread count.
fn scatter(
    order: &[u32],
    pairs_of: &[usize],
    tile_of_pair: &[u32],
    offsets: &[usize],
    lists: (&mut [u32], &mut [u32]),
    scratch: (&mut [u32], &mut [usize]),
) {
    let (ids, entry_from_pair) = lists;
    let (pair_from_entry, cursor) = scratch;
    let n_tiles = offsets.len() - 1;
    let cuts = Cuts {
        groups: rayon::current_num_threads().clamp(1, n_tiles.max(1)),
        n_tiles,
        total: tile_of_pair.len(),
        offsets,
    };
    cursor.copy_from_slice(&offsets[..n_tiles]);
    let visit = Visit {
        order,
        pairs_of,
        tile_of_pair,
        cuts: &cuts,
    };
    visit.tile_ranges(0..cuts.groups, ids, pair_from_entry, cursor);
    inverse_ranges(&cuts, 0..cuts.groups, entry_from_pair, pair_from_entry);
}

/// Where [`scatter`] cuts its work.
struct Cuts<'a> {
    groups: usize,
    n_tiles: usize,
    /// Pairs (entries) in all.
    total: usize,
    offsets: &'a [usize],
}

impl Cuts<'_> {
    /// First tile of tile range `k` (`n_tiles` for `k = groups`).
    fn tile(&self, k: usize) -> usize {
        if k == self.groups {
            self.n_tiles
        } else {
            let target = k * self.total / self.groups;
            self.offsets[..self.n_tiles].partition_point(|&o| o < target)
        }
    }

    /// First entry of tile range `k`.
    fn entry(&self, k: usize) -> usize {
        self.offsets[self.tile(k)]
    }

    /// First pair of pair range `k`.
    fn pair(&self, k: usize) -> usize {
        k * self.total / self.groups
    }
}

/// What every tile range's task of [`scatter`] reads.
struct Visit<'a> {
    order: &'a [u32],
    pairs_of: &'a [usize],
    tile_of_pair: &'a [u32],
    cuts: &'a Cuts<'a>,
}

impl Visit<'_> {
    /// Tile ranges `ks`, split in halves across the pool; `ids` and `pair_from_entry` start at
    /// the first entry of range `ks.start`, `cursor` at its first tile.
    fn tile_ranges(
        &self,
        ks: std::ops::Range<usize>,
        ids: &mut [u32],
        pair_from_entry: &mut [u32],
        cursor: &mut [usize],
    ) {
        match ks.len() {
            0 => {}
            1 => self.tile_range(ks.start, ids, pair_from_entry, cursor),
            len => {
                let mid = ks.start + len / 2;
                let entries = self.cuts.entry(mid) - self.cuts.entry(ks.start);
                let tiles = self.cuts.tile(mid) - self.cuts.tile(ks.start);
                let (ids_a, ids_b) = ids.split_at_mut(entries);
                let (pfe_a, pfe_b) = pair_from_entry.split_at_mut(entries);
                let (cur_a, cur_b) = cursor.split_at_mut(tiles);
                rayon::join(
                    || self.tile_ranges(ks.start..mid, ids_a, pfe_a, cur_a),
                    || self.tile_ranges(mid..ks.end, ids_b, pfe_b, cur_b),
                );
            }
        }
    }

    /// Tile range `k`: every Gaussian in depth order, its pairs in the range placed.
    fn tile_range(
        &self,
        k: usize,
        ids: &mut [u32],
        pair_from_entry: &mut [u32],
        cursor: &mut [usize],
    ) {
        let (t0, t1) = (self.cuts.tile(k) as u32, self.cuts.tile(k + 1) as u32);
        let base = self.cuts.entry(k);
        for (rank, &id) in self.order.iter().enumerate() {
            let pairs = self.pairs_of[id as usize]..self.pairs_of[id as usize + 1];
            // A Gaussian's pairs are in ascending tile order: skip it when none is ours.
            if pairs.is_empty()
                || self.tile_of_pair[pairs.end - 1] < t0
                || self.tile_of_pair[pairs.start] >= t1
            {
                continue;
            }
            for p in pairs {
                let t = self.tile_of_pair[p];
                if (t0..t1).contains(&t) {
                    let slot = &mut cursor[(t - t0) as usize];
                    ids[*slot - base] = rank as u32;
                    pair_from_entry[*slot - base] = p as u32;
                    *slot += 1;
                }
            }
        }
    }
}

/// `entry_from_pair[pair_from_entry[e]] = e` over pair ranges `ks`, split in halves across the
/// pool (`entry_from_pair` starts at the first pair of range `ks.start`).
fn inverse_ranges(
    cuts: &Cuts<'_>,
    ks: std::ops::Range<usize>,
    entry_from_pair: &mut [u32],
    pair_from_entry: &[u32],
) {
    match ks.len() {
        0 => {}
        1 => {
            let (p0, p1) = (cuts.pair(ks.start), cuts.pair(ks.end));
            for (e, &p) in pair_from_entry.iter().enumerate() {
                let p = p as usize;
                if (p0..p1).contains(&p) {
                    entry_from_pair[p - p0] = e as u32;
                }
            }
        }
        len => {
            let mid = ks.start + len / 2;
            let (a, b) = entry_from_pair.split_at_mut(cuts.pair(mid) - cuts.pair(ks.start));
            rayon::join(
                || inverse_ranges(cuts, ks.start..mid, a, pair_from_entry),
                || inverse_ranges(cuts, mid..ks.end, b, pair_from_entry),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The lists by their definition: per tile, the ranks of the Gaussians that touch it, in
    /// ascending rank; per Gaussian, the positions of its entries in ascending tile order.
    fn reference(
        rects: &[Option<[u32; 4]>],
        depth: &[f32],
        tiles_x: u32,
        tiles_y: u32,
        touches: impl Fn(u32, u32, u32) -> bool,
    ) -> TileLists {
        let mut order: Vec<u32> = (0..rects.len() as u32)
            .filter(|&i| rects[i as usize].is_some())
            .collect();
        order.sort_by(|&a, &b| {
            depth[a as usize]
                .total_cmp(&depth[b as usize])
                .then(a.cmp(&b))
        });
        let tiles_of = |i: usize| -> Vec<u32> {
            let Some([x0, y0, x1, y1]) = rects[i] else {
                return Vec::new();
            };
            (y0..=y1)
                .flat_map(|ty| (x0..=x1).map(move |tx| (tx, ty)))
                .filter(|&(tx, ty)| touches(i as u32, tx, ty))
                .map(|(tx, ty)| ty * tiles_x + tx)
                .collect()
        };
        let mut lists = TileLists {
            offsets: vec![0],
            ..TileLists::default()
        };
        for t in 0..tiles_x * tiles_y {
            for (rank, &id) in order.iter().enumerate() {
                if tiles_of(id as usize).contains(&t) {
                    lists.ids.push(rank as u32);
                }
            }
            lists.offsets.push(lists.ids.len());
        }
        lists.order = order.clone();
        lists.pairs_of = vec![0];
        for i in 0..rects.len() {
            let rank = order.iter().position(|&id| id as usize == i);
            for t in tiles_of(i) {
                let list = lists.offsets[t as usize]..lists.offsets[t as usize + 1];
                let e = list
                    .clone()
                    .find(|&e| Some(lists.ids[e] as usize) == rank)
                    .unwrap();
                lists.entry_from_pair.push(e as u32);
            }
            lists.pairs_of.push(lists.entry_from_pair.len());
        }
        lists
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        /// The parallel binning gives the lists of their definition for 1, 2 and 3 threads
        /// (ties in depth included), reusing one set of buffers across scenes.
        #[test]
        fn binning_matches_the_definition_for_any_thread_count(
            parts in proptest::collection::vec(
                (prop::option::weighted(0.85, (0u32..7, 0u32..5, 0u32..4, 0u32..3)), 0u8..6),
                0..90,
            ),
            (tiles_x, tiles_y) in (1u32..8, 1u32..6),
            salt in any::<u32>(),
        ) {
            let rects: Vec<Option<[u32; 4]>> = parts
                .iter()
                .map(|(r, _)| r.map(|(x, y, w, h)| {
                    let (x0, y0) = (x.min(tiles_x - 1), y.min(tiles_y - 1));
                    [x0, y0, (x0 + w).min(tiles_x - 1), (y0 + h).min(tiles_y - 1)]
                }))
                .collect();
            let depth: Vec<f32> = parts.iter().map(|&(_, d)| 0.5 + f32::from(d)).collect();
            let touches = |id: u32, tx: u32, ty: u32| {
                !(id ^ salt)
                    .wrapping_mul(2_654_435_761)
                    .wrapping_add(tx * 31 + ty * 17)
                    .is_multiple_of(5)
            };
            let expected = reference(&rects, &depth, tiles_x, tiles_y, touches);
            let (mut lists, mut scratch) = (TileLists::default(), BinScratch::default());
            for threads in [1, 2, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| {
                    bin_into(
                        &rects,
                        &depth,
                        tiles_x,
                        tiles_y,
                        tiles_where(tiles_x, touches),
                        &mut lists,
                        &mut scratch,
                    );
                });
                prop_assert_eq!(&lists, &expected, "{} threads", threads);
            }
        }
    }

    #[test]
    fn lists_are_depth_ordered_with_index_tie_break() {
        let rects = [
            Some([0, 0, 1, 0]),
            None,
            Some([1, 0, 1, 0]),
            Some([0, 0, 0, 0]),
        ];
        let depth = [2.0, 1.0, 2.0, 0.5];
        let lists = bin(&rects, &depth, 2, 1, |id, tx, _| id != 0 || tx == 1);
        assert_eq!(lists.order, &[3, 0, 2]);
        assert_eq!(lists.tile(0), &[0]);
        assert_eq!(lists.tile(1), &[1, 2]);
        assert_eq!(lists.entries_of(0), &[1]);
        assert!(lists.entries_of(1).is_empty());
        assert_eq!(lists.entries_of(2), &[2]);
        assert_eq!(lists.entries_of(3), &[0]);
    }
}
