//! What the rasterizer benches (CPU and wgpu) share, so both measure the same Gaussians from the
//! same camera the same way: the scene, and the `forward` and `forward_backward` cases.

use std::hint::black_box;

use criterion::BenchmarkGroup;
use criterion::measurement::Measurement;
use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, Gaussians, PixelGrads, Rasterizer, RenderOptions, sh_coeff_count};

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

/// Adds `{prefix}forward` and `{prefix}forward_backward` of `r` on `g` seen from `cam` to
/// `group`; the backward pass gets the same constant colour and alpha gradients in every bench.
pub fn forward_and_backward<M: Measurement>(
    group: &mut BenchmarkGroup<'_, M>,
    prefix: &str,
    r: &impl Rasterizer,
    g: &Gaussians,
    cam: &Camera,
    opts: &RenderOptions,
) {
    let d_color = vec![[0.1f32, -0.2, 0.3]; cam.pixel_count()];
    let d_alpha = vec![0.05f32; cam.pixel_count()];
    group.bench_function(format!("{prefix}forward"), |b| {
        b.iter(|| r.forward(black_box(g.view()), cam, opts).unwrap());
    });
    group.bench_function(format!("{prefix}forward_backward"), |b| {
        b.iter(|| {
            let f = r.forward(black_box(g.view()), cam, opts).unwrap();
            r.backward(
                g.view(),
                cam,
                opts,
                &f,
                PixelGrads::from_color(&d_color).with_alpha(&d_alpha),
            )
            .unwrap()
        });
    });
}
