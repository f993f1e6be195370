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
        touches,
        &mut lists,
        &mut BinScratch::default(),
    );
    lists
}

/// [`bin`] into `lists`, reusing its buffers and `scratch`'s: the same lists, without fresh
/// allocations once the buffers are large enough.
pub(crate) fn bin_into(
    rects: &[Option<[u32; 4]>],
    depth: &[f32],
    tiles_x: u32,
    tiles_y: u32,
    touches: impl Fn(u32, u32, u32) -> bool + Sync,
    lists: &mut TileLists,
    scratch: &mut BinScratch,
) {
    let n = rects.len();
    let BinScratch {
        touched,
        tile_of_pair,
        keys,
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
                if let Some([x0, y0, x1, y1]) = *rect {
                    let id = (c * CHUNK + k) as u32;
                    for ty in y0..=y1 {
                        for tx in x0..=x1 {
                            if touches(id, tx, ty) {
                                tiles.push(ty * tiles_x + tx);
                            }
                        }
                    }
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
    cursor.clear();
    cursor.extend_from_slice(&offsets[..n_tiles]);
    let (ids, entry_from_pair, order) =
        (&mut lists.ids, &mut lists.entry_from_pair, &mut lists.order);
    ids.clear();
    ids.resize(tile_of_pair.len(), 0);
    entry_from_pair.clear();
    entry_from_pair.resize(tile_of_pair.len(), 0);
    order.clear();
    order.extend(keys.iter().map(|&key| key as u32));
    for (rank, &id) in order.iter().enumerate() {
        let id = id as usize;
        for p in pairs_of[id]..pairs_of[id + 1] {
            let t = tile_of_pair[p] as usize;
            ids[cursor[t]] = rank as u32;
            entry_from_pair[p] = cursor[t] as u32;
            cursor[t] += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
