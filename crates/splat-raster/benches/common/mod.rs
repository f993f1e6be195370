//! The benchmark scene shared by the rasterizer benches (CPU and wgpu), so both measure the same
//! Gaussians from the same camera.

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, Gaussians, sh_coeff_count};

/// `n` random Gaussians (SH degree 3) in a cube of side 2, sized to their spacing, and a
/// `size`×`size` camera at distance ~4.
pub fn scene(n: usize, size: u32, seed: u64) -> (Gaussians, Camera) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let degree = 3;
    let spacing = (8.0 / n as f32).cbrt();
    let mut g = Gaussians::with_degree(degree);
    for _ in 0..n {
        g.means
            .push(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        g.log_scales.push(std::array::from_fn(|_| {
            (spacing * rng.random_range(0.2f32..0.8)).ln()
        }));
        g.rotations
            .push(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        g.opacity_logits.push(rng.random_range(-1.0f32..3.0));
        for c in 0..sh_coeff_count(degree) {
            let amp = if c == 0 { 1.0 } else { 0.1 };
            for _ in 0..3 {
                g.sh.push(rng.random_range(-amp..amp));
            }
        }
    }
    let cam = Camera::look_at(
        size,
        size,
        0.8,
        Vec3::new(0.5, -4.0, 1.0),
        Vec3::ZERO,
        Vec3::Z,
    );
    (g, cam)
}
