//! Forward and forward+backward at 10K Gaussians / 256×256 and 100K Gaussians / 800×800, on a
//! deterministic random scene: Gaussians in a cube of side 2 seen from distance 4, sized to their
//! spacing (a few pixels on screen), opacities mostly high. Throughput is reported in
//! Gaussian-pixel evaluations: per tile, for each list entry processed, the pixels of the
//! Gaussian's bounding box inside the tile (what the inner loop visits).
//!
//! Each case runs the default SIMD kernels (`forward`, `forward_backward`) and, for the ratio
//! in the same run, the scalar reference kernels (`scalar_forward`, `scalar_forward_backward`:
//! the CPU backend's kernels before the SIMD ones, `CpuKernel::Scalar`).
//!
//! Each case is measured twice: in wall-clock time (`wall/...`) and in process CPU time summed
//! over all threads (`cpu/...`, from `/proc/self/task/*/schedstat`), which is far less disturbed
//! by other processes competing for the cores than wall-clock time.

mod common;

use bench_support::CpuTime;
use criterion::measurement::{Measurement, WallTime};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use splat_raster::{CpuKernel, CpuRasterizer, Rasterizer, RenderOptions};

fn bench_wall(c: &mut Criterion<WallTime>) {
    bench(c, "wall");
}

fn bench_cpu(c: &mut Criterion<CpuTime>) {
    bench(c, "cpu");
}

fn bench<M: Measurement>(c: &mut Criterion<M>, clock: &str) {
    let r = CpuRasterizer::new();
    let opts = RenderOptions {
        background: [1.0, 1.0, 1.0],
        sh_degree: None,
    };
    for (n, size) in [(10_000usize, 256u32), (100_000, 800)] {
        let (g, cam) = common::scene(n, size, 7);
        let fwd = r.forward(g.view(), &cam, &opts).unwrap();
        let evals = fwd.pair_evaluations();
        if clock == "wall" {
            eprintln!(
                "scene {n} Gaussians {size}x{size}: {}; {} Gaussian-tile pairs; {evals} Gaussian-pixel evaluations; {:.2} contributors per pixel",
                fwd.stats,
                fwd.tile_pairs(),
                fwd.mean_contributors()
            );
        }
        let mut group = c.benchmark_group(format!("{clock}/{}k_{size}", n / 1000));
        group.throughput(Throughput::Elements(evals));
        for (prefix, kernel) in [("", CpuKernel::Simd), ("scalar_", CpuKernel::Scalar)] {
            let r = CpuRasterizer::new().with_kernel(kernel);
            common::forward_and_backward(&mut group, prefix, &r, &g, &cam, &opts);
        }
        group.finish();
    }
}

criterion_group!(wall, bench_wall);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(CpuTime::total());
    targets = bench_cpu
}
criterion_main!(wall, cpu);
