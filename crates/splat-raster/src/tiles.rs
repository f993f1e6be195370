//! Tile binning: per 16×16 tile, the ids of the Gaussians whose extent touches it, in depth order
//! (camera z ascending, ties broken by index, so the order is total and deterministic).

use rayon::prelude::*;

/// Per-tile Gaussian lists in one flat array: tile `t` owns `ids[offsets[t]..offsets[t + 1]]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct TileLists {
    pub offsets: Vec<usize>,
    pub ids: Vec<u32>,
}

impl TileLists {
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.ids[self.offsets[t]..self.offsets[t + 1]]
    }
}

/// Bins drawn Gaussians into tiles. `rects[i]` is Gaussian `i`'s inclusive tile rectangle
/// `[x0, y0, x1, y1]` (None when culled) and `depth[i]` its camera z (> 0 when drawn); within the
/// rectangle, only tiles `(tx, ty)` with `touches(i, tx, ty)` get the Gaussian.
pub(crate) fn bin(
    rects: &[Option<[u32; 4]>],
    depth: &[f32],
    tiles_x: u32,
    tiles_y: u32,
    touches: impl Fn(u32, u32, u32) -> bool,
) -> TileLists {
    // z > 0 is finite and positive, so its bit pattern orders like the number.
    let mut keys: Vec<u64> = rects
        .iter()
        .enumerate()
        .filter(|(_, r)| r.is_some())
        .map(|(i, _)| (u64::from(depth[i].to_bits()) << 32) | i as u64)
        .collect();
    keys.par_sort_unstable();
    let n_tiles = tiles_x as usize * tiles_y as usize;
    // (tile, id) pairs in depth order, then a stable counting sort by tile.
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for &key in &keys {
        let id = (key & 0xffff_ffff) as u32;
        let [x0, y0, x1, y1] = rects[id as usize].unwrap_or_default();
        for ty in y0..=y1 {
            for tx in x0..=x1 {
                if touches(id, tx, ty) {
                    pairs.push((ty * tiles_x + tx, id));
                }
            }
        }
    }
    let mut offsets = vec![0usize; n_tiles + 1];
    for &(t, _) in &pairs {
        offsets[t as usize + 1] += 1;
    }
    for t in 0..n_tiles {
        offsets[t + 1] += offsets[t];
    }
    let mut cursor = offsets[..n_tiles].to_vec();
    let mut ids = vec![0u32; pairs.len()];
    for &(t, id) in &pairs {
        ids[cursor[t as usize]] = id;
        cursor[t as usize] += 1;
    }
    TileLists { offsets, ids }
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
        assert_eq!(lists.tile(0), &[3]);
        assert_eq!(lists.tile(1), &[0, 2]);
    }
}
