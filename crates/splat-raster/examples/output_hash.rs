//! Prints a hash of the CPU backend's outputs (images and gradients, bit for bit) on the bench
//! scenes, so that a change meant to keep results bit-identical can be checked before and after:
//! `cargo run --release -p splat-raster --example output_hash`.

// The benches' scene; their criterion cases (`forward_and_backward`) are not used here.
#[path = "../benches/common/mod.rs"]
#[allow(dead_code)]
mod common;

use std::hash::{DefaultHasher, Hasher};

use splat_raster::{CpuRasterizer, PixelGrads, Rasterizer, RenderOptions};

fn main() {
    let r = CpuRasterizer::new();
    let opts = RenderOptions {
        background: [1.0, 1.0, 1.0],
        sh_degree: None,
    };
    for (n, size) in [(2_000usize, 96u32), (10_000, 256), (100_000, 800)] {
        let (g, cam) = common::scene(n, size, 7);
        let fwd = r.forward(g.view(), &cam, &opts).unwrap();
        let npix = cam.pixel_count();
        let d_color: Vec<[f32; 3]> = (0..npix)
            .map(|p| [0.1, -0.2, 0.3].map(|v: f32| v * ((p % 7) as f32 - 3.0)))
            .collect();
        let d_alpha: Vec<f32> = (0..npix).map(|p| 0.05 * ((p % 5) as f32 - 2.0)).collect();
        let d_depth: Vec<f32> = (0..npix).map(|p| 0.01 * ((p % 3) as f32 - 1.0)).collect();
        let grads = r
            .backward(
                g.view(),
                &cam,
                &opts,
                &fwd,
                PixelGrads::from_color(&d_color)
                    .with_alpha(&d_alpha)
                    .with_depth(&d_depth),
            )
            .unwrap()
            .grads;
        let mut image = DefaultHasher::new();
        for v in fwd
            .color
            .as_flattened()
            .iter()
            .chain(&fwd.alpha)
            .chain(&fwd.depth)
        {
            image.write_u32(v.to_bits());
        }
        let mut grad = DefaultHasher::new();
        for v in grads
            .means
            .as_flattened()
            .iter()
            .chain(grads.log_scales.as_flattened())
            .chain(grads.rotations.as_flattened())
            .chain(&grads.opacity_logits)
            .chain(&grads.sh)
            .chain(grads.means2d.as_flattened())
            .chain(fwd.radii())
        {
            grad.write_u32(v.to_bits());
        }
        println!(
            "{n} Gaussians {size}x{size}: evaluations {}, images {:016x}, gradients {:016x}",
            fwd.pair_evaluations(),
            image.finish(),
            grad.finish()
        );
    }
}
