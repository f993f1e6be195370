//! Photometric loss + gradient (plain reference and the fast workspace, in one run) and SSIM at
//! 400×400 (the size of a D-NeRF image at half resolution).

use bench_support::{CpuTime, clock_prefix};
use criterion::measurement::{Measurement, WallTime};
use criterion::{Criterion, criterion_group, criterion_main};
use evogs_metrics::{ImageSize, LossWorkspace, photometric_loss, ssim};
use std::hint::black_box;

fn images(size: ImageSize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let gt: Vec<[f32; 3]> = (0..size.pixels())
        .map(|i| {
            let (x, y) = ((i % size.width) as f32, (i / size.width) as f32);
            [
                0.5 + 0.4 * (x * 0.05).sin(),
                0.5 + 0.4 * (y * 0.07).cos(),
                ((x + y) * 0.01).fract(),
            ]
        })
        .collect();
    let rendered = gt
        .iter()
        .enumerate()
        .map(|(i, p)| {
            p.map(|v| (v + 0.05 * (((i * 7919) % 13) as f32 / 13.0 - 0.5)).clamp(0.0, 1.0))
        })
        .collect();
    (rendered, gt)
}

fn bench<M: Measurement + 'static>(c: &mut Criterion<M>) {
    let size = ImageSize::new(400, 400);
    let (rendered, gt) = images(size);
    let mut group = c.benchmark_group(format!("{}metrics_400x400", clock_prefix::<M>()));
    group.bench_function("loss_and_gradient", |b| {
        b.iter(|| photometric_loss(size, black_box(&rendered), black_box(&gt)).unwrap());
    });
    let mut workspace = LossWorkspace::new();
    group.bench_function("loss_and_gradient_fast", |b| {
        b.iter(|| {
            workspace
                .compute(size, black_box(&rendered), black_box(&gt))
                .unwrap()
        });
    });
    group.bench_function("ssim", |b| {
        b.iter(|| ssim(size, black_box(&rendered), black_box(&gt)).unwrap());
    });
    group.finish();
}

criterion_group!(benches, bench::<WallTime>);
criterion_group! {
    name = cpu_benches;
    config = Criterion::default().with_measurement(CpuTime::wall_equivalent());
    targets = bench::<CpuTime>
}
criterion_main!(benches, cpu_benches);
