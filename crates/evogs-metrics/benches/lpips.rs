//! LPIPS of one 400×400 pair (a D-NeRF image at half resolution), AlexNet and VGG16 backbones.
//! Needs the weights (`scripts/lpips-weights`).

use bench_support::{CpuTime, clock_prefix};
use criterion::measurement::{Measurement, WallTime};
use criterion::{Criterion, criterion_group, criterion_main};
use evogs_metrics::ImageSize;
use evogs_metrics::lpips::{Backbone, Lpips};
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
    let mut group = c.benchmark_group(format!("{}lpips_400x400", clock_prefix::<M>()));
    group.sample_size(10);
    for backbone in Backbone::ALL {
        let lpips = Lpips::find(backbone, None).unwrap_or_else(|e| panic!("{e}"));
        group.bench_function(backbone.name(), |b| {
            b.iter(|| {
                lpips
                    .distance(size, black_box(&rendered), black_box(&gt))
                    .unwrap()
            });
        });
    }
    group.finish();
}

criterion_group!(benches, bench::<WallTime>);
criterion_group! {
    name = cpu_benches;
    config = Criterion::default().with_measurement(CpuTime::wall_equivalent());
    targets = bench::<CpuTime>
}
criterion_main!(benches, cpu_benches);
