//! Morton (Z-order) sorting of points, the order in which the compressed PLY's writers store
//! Gaussians so that each chunk of 256 is spatially compact (tight per-chunk bounds, hence fine
//! quantisation steps).

/// Spreads the low 10 bits of `v` so that bit `k` moves to bit `3k`.
fn spread_bits(v: u32) -> u32 {
    let mut v = v & 0x0000_03ff;
    v = (v ^ (v << 16)) & 0xff00_00ff;
    v = (v ^ (v << 8)) & 0x0300_f00f;
    v = (v ^ (v << 4)) & 0x030c_30c3;
    (v ^ (v << 2)) & 0x0924_9249
}

/// The 30-bit Morton code of a cell `[x, y, z]` (each below 1024): x in bits 0, 3, …, y in 1, 4, …,
/// z in 2, 5, ….
pub fn morton_code([x, y, z]: [u32; 3]) -> u32 {
    spread_bits(x) | (spread_bits(y) << 1) | (spread_bits(z) << 2)
}

/// Sorts `indices` (into `points`, all finite) into Morton order: each point's cell on a 1024³
/// grid over the bounding box of the points in `indices`, sorted stably by code; a run of more
/// than 256 points sharing one code is sorted again over its own bounding box. Points all at one
/// place keep their order.
pub fn sort_morton(points: &[[f32; 3]], indices: &mut [usize]) {
    if indices.is_empty() {
        return;
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for &i in indices.iter() {
        for k in 0..3 {
            lo[k] = lo[k].min(points[i][k]);
            hi[k] = hi[k].max(points[i][k]);
        }
    }
    let extent = [0, 1, 2].map(|k| hi[k] - lo[k]);
    if extent.iter().any(|e| !e.is_finite()) || extent.iter().all(|&e| e == 0.0) {
        return;
    }
    let scale = extent.map(|e| if e == 0.0 { 0.0 } else { 1024.0 / e });
    let code = |i: usize| {
        morton_code([0, 1, 2].map(|k| ((points[i][k] - lo[k]) * scale[k]).min(1023.0) as u32))
    };
    let mut keyed: Vec<(u32, usize)> = indices.iter().map(|&i| (code(i), i)).collect();
    keyed.sort_by_key(|&(c, _)| c);
    for (slot, &(_, i)) in indices.iter_mut().zip(&keyed) {
        *slot = i;
    }
    let mut start = 0;
    while start < keyed.len() {
        let end = start + keyed[start..].partition_point(|&(c, _)| c == keyed[start].0);
        if end - start > 256 {
            sort_morton(points, &mut indices[start..end]);
        }
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_interleave_x_then_y_then_z() {
        assert_eq!(morton_code([1, 0, 0]), 0b001);
        assert_eq!(morton_code([0, 1, 0]), 0b010);
        assert_eq!(morton_code([0, 0, 1]), 0b100);
        assert_eq!(morton_code([2, 0, 0]), 0b001_000);
        assert_eq!(morton_code([1023, 1023, 1023]), (1 << 30) - 1);
    }

    #[test]
    fn the_eight_corners_of_a_cube_sort_in_z_order() {
        // Listed in reverse Z-order; sorted, corner k has bit 0 = x, bit 1 = y, bit 2 = z.
        let points: Vec<[f32; 3]> = (0..8)
            .rev()
            .map(|k| [(k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32])
            .collect();
        let mut order: Vec<usize> = (0..8).collect();
        sort_morton(&points, &mut order);
        assert_eq!(order, [7, 6, 5, 4, 3, 2, 1, 0]);
    }

    #[test]
    fn identical_points_keep_their_order_and_dense_clusters_are_refined() {
        let same = vec![[0.5f32; 3]; 300];
        let mut order: Vec<usize> = (0..300).collect();
        sort_morton(&same, &mut order);
        assert!(order.iter().enumerate().all(|(k, &i)| k == i));
        // 300 points packed into one grid cell of a wide box, listed in decreasing x: one code
        // at the first level, refined by x in the second.
        let mut points: Vec<[f32; 3]> = (0..300)
            .map(|k| [1e-6 * (300 - k) as f32, 0.0, 0.0])
            .collect();
        points.push([1000.0, 0.0, 0.0]);
        let mut order: Vec<usize> = (0..301).collect();
        sort_morton(&points, &mut order);
        assert_eq!(order[0], 299);
        assert_eq!(order[299], 0);
        assert_eq!(order[300], 300);
    }
}
