//! Initial Gaussians: random points in a cube (3DGS/D-3DGS practice for Blender/D-NeRF scenes,
//! `scene/dataset_readers.py`: 100 000 points uniform in [-1.3, 1.3]³ with random colours
//! `shs = rand/255`), initialised as 3DGS's `create_from_pcd`: log-scale `log(sqrt(mean squared
//! distance to the 3 nearest neighbours))` (clamped below at 1e-7 as `distCUDA2`), identity
//! rotation, opacity 0.1, SH DC from the colour and higher bands zero.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_core::sh::dc_from_rgb;
use splat_core::{Gaussians, logit, sh_coeff_count};

/// `count` random Gaussians in `[-half, half]³` at SH degree `sh_degree`, deterministic for a
/// seed.
pub fn random_gaussians(count: usize, half: f32, sh_degree: u32, seed: u64) -> Gaussians {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x1417_0000_0000_0001);
    let means: Vec<[f32; 3]> = (0..count)
        .map(|_| std::array::from_fn(|_| rng.random_range(-half..half)))
        .collect();
    // 3DGS: `shs = rand / 255`, used directly as SH DC after SH2RGB/RGB2SH round trip.
    let dc: Vec<[f32; 3]> = (0..count)
        .map(|_| std::array::from_fn(|_| rng.random::<f32>() / 255.0))
        .collect();
    from_points(means, &dc, sh_degree)
}

/// Gaussians from a dataset's point cloud (3DGS `create_from_pcd`): one per point, SH DC
/// `RGB2SH(colour) = (colour − 0.5) / C0`, higher bands zero.
pub fn gaussians_from_point_cloud(points: &evogs_io::PointCloud, sh_degree: u32) -> Gaussians {
    let means = points.positions.iter().map(|p| p.to_array()).collect();
    let dc: Vec<[f32; 3]> = points
        .colours
        .iter()
        .map(|c| c.to_array().map(dc_from_rgb))
        .collect();
    from_points(means, &dc, sh_degree)
}

/// Gaussians at `means` with SH DC `dc` (higher bands zero), initialised as 3DGS's
/// `create_from_pcd` (see the module doc).
fn from_points(means: Vec<[f32; 3]>, dc: &[[f32; 3]], sh_degree: u32) -> Gaussians {
    let count = means.len();
    let stride = sh_coeff_count(sh_degree) * 3;
    let mut sh = vec![0.0f32; count * stride];
    for (row, dc) in sh.chunks_exact_mut(stride).zip(dc) {
        row[..3].copy_from_slice(dc);
    }
    let log_scales = mean_knn_sq_dist(&means, 3)
        .into_iter()
        .map(|d2| [0.5 * d2.max(1e-7).ln(); 3])
        .collect();
    let opacity = logit(0.1);
    Gaussians {
        sh_degree,
        means,
        log_scales,
        rotations: vec![[1.0, 0.0, 0.0, 0.0]; count],
        opacity_logits: vec![opacity; count],
        sh,
    }
}

/// Mean squared distance of every point to its `k` nearest other points (fewer when there are
/// fewer points; 0 for a single point), via a uniform grid.
pub fn mean_knn_sq_dist(points: &[[f32; 3]], k: usize) -> Vec<f32> {
    use rayon::prelude::*;
    let n = points.len();
    if n <= 1 || k == 0 {
        return vec![0.0; n];
    }
    let k = k.min(n - 1);
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let span = (0..3)
        .map(|a| hi[a] - lo[a])
        .fold(0.0f32, f32::max)
        .max(1e-6);
    // About two points per cell for a uniform cloud.
    let cells_per_axis = ((n as f32 / 2.0).cbrt().ceil() as usize).clamp(1, 256);
    let cell = span / cells_per_axis as f32 * 1.0001;
    let dims: [usize; 3] =
        std::array::from_fn(|a| (((hi[a] - lo[a]) / cell) as usize + 1).min(cells_per_axis + 1));
    let cell_of = |p: &[f32; 3]| -> [usize; 3] {
        std::array::from_fn(|a| (((p[a] - lo[a]) / cell) as usize).min(dims[a] - 1))
    };
    let flat = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    let mut start = vec![0u32; dims[0] * dims[1] * dims[2] + 1];
    for p in points {
        start[flat(cell_of(p)) + 1] += 1;
    }
    for i in 1..start.len() {
        start[i] += start[i - 1];
    }
    let mut fill = start.clone();
    let mut point_from_slot = vec![0u32; n];
    for (i, p) in points.iter().enumerate() {
        let c = flat(cell_of(p));
        point_from_slot[fill[c] as usize] = i as u32;
        fill[c] += 1;
    }
    points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let c = cell_of(p);
            let mut best: Vec<f32> = Vec::with_capacity(k + 1);
            let max_ring = dims.iter().copied().max().unwrap_or(1);
            for ring in 0..=max_ring {
                let r = ring as isize;
                for dz in -r..=r {
                    for dy in -r..=r {
                        for dx in -r..=r {
                            if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                                continue;
                            }
                            let q = [c[0] as isize + dx, c[1] as isize + dy, c[2] as isize + dz];
                            if (0..3).any(|a| q[a] < 0 || q[a] >= dims[a] as isize) {
                                continue;
                            }
                            let f = flat([q[0] as usize, q[1] as usize, q[2] as usize]);
                            for &j in &point_from_slot[start[f] as usize..start[f + 1] as usize] {
                                if j as usize == i {
                                    continue;
                                }
                                let o = &points[j as usize];
                                let d2 = (0..3).map(|a| (o[a] - p[a]).powi(2)).sum::<f32>();
                                if best.len() < k || d2 < best[k - 1] {
                                    let at = best.partition_point(|&b| b <= d2);
                                    best.insert(at, d2);
                                    best.truncate(k);
                                }
                            }
                        }
                    }
                }
                // Points in rings beyond `ring` are farther than `ring · cell`.
                let reach = ring as f32 * cell;
                if best.len() == k && best[k - 1] <= reach * reach {
                    break;
                }
            }
            best.iter().sum::<f32>() / best.len().max(1) as f32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute(points: &[[f32; 3]], k: usize) -> Vec<f32> {
        points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut d: Vec<f32> = points
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, o)| (0..3).map(|a| (o[a] - p[a]).powi(2)).sum())
                    .collect();
                d.sort_by(f32::total_cmp);
                let k = k.min(d.len());
                d[..k].iter().sum::<f32>() / k.max(1) as f32
            })
            .collect()
    }

    proptest! {
        #[test]
        fn grid_knn_matches_brute_force(
            pts in prop::collection::vec(prop::array::uniform3(-3.0f32..3.0), 1..120),
            squash in prop::bool::ANY,
        ) {
            // Squashing one axis makes the cloud strongly anisotropic (empty cells, long rings).
            let pts: Vec<[f32; 3]> = pts
                .into_iter()
                .map(|p| if squash { [p[0], p[1] * 0.01, p[2]] } else { p })
                .collect();
            let got = mean_knn_sq_dist(&pts, 3);
            let want = brute(&pts, 3);
            for (g, w) in got.iter().zip(&want) {
                prop_assert!((g - w).abs() <= 1e-5 * w.max(1.0), "{g} vs {w}");
            }
        }
    }

    #[test]
    fn random_init_is_deterministic_and_inside_the_box() {
        let a = random_gaussians(500, 1.3, 3, 7);
        assert_eq!(a, random_gaussians(500, 1.3, 3, 7));
        assert_ne!(a.means, random_gaussians(500, 1.3, 3, 8).means);
        assert!(a.means.iter().flatten().all(|v| v.abs() <= 1.3));
        assert_eq!(a.sh.len(), 500 * 48);
        assert!(a.log_scales.iter().all(|s| s[0].is_finite() && s[0] < 0.0));
        assert!((1.0 / (1.0 + (-a.opacity_logits[0]).exp()) - 0.1).abs() < 1e-6);
    }
}
