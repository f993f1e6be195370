//! The wgpu backend on the scenes of `benches/raster.rs` (10K Gaussians / 256×256 and 100K /
//! 800×800, same generator and seed): forward, and forward + backward, wall-clock time including
//! the uploads and read-backs of every call. On lavapipe (software Vulkan) the figures are a
//! sanity check, not GPU performance.

mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use splat_raster::{Rasterizer, RenderOptions, WgpuRasterizer};

fn bench(c: &mut Criterion) {
    let r = WgpuRasterizer::new().expect("the wgpu bench needs an adapter");
    eprintln!("adapter: {}; atomics {:?}", r.adapter(), r.atomics());
    let opts = RenderOptions {
        background: [1.0, 1.0, 1.0],
        sh_degree: None,
    };
    for (n, size) in [(10_000usize, 256u32), (100_000, 800)] {
        let (g, cam) = common::scene(n, size, 7);
        let fwd = r.forward(g.view(), &cam, &opts).unwrap();
        let evals = fwd.pair_evaluations();
        eprintln!(
            "scene {n} Gaussians {size}x{size}: {}; {} Gaussian-tile pairs; {evals} Gaussian-pixel evaluations",
            fwd.stats,
            fwd.tile_pairs(),
        );
        let mut group = c.benchmark_group(format!("wgpu/{}k_{size}", n / 1000));
        group.throughput(Throughput::Elements(evals));
        common::forward_and_backward(&mut group, "", &r, &g, &cam, &opts);
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
