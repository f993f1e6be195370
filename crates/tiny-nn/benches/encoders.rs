//! Throughput of the field encoders of the 4DGaussians and Grid4D backbones, forward and
//! forward + backward (table or plane gradients and input gradients), f32 and f16 storage:
//!
//! - `hashgrid/spatial`: Grid4D's canonical grid (3D, 16 levels × 2 features, 16 → 2048,
//!   T = 2^19, smoothstep, zero outside the box).
//! - `hashgrid/temporal`: one of Grid4D's three xyt grids (3D, 32 levels × 2, [8, 8, 8] →
//!   [32, 32, 16], all levels dense).
//! - `hexplane`: 4DGaussians' D-NeRF HexPlane (32 channels, space 64 × [1, 2], time 100,
//!   product).
//!
//! Inputs are uniform in the box (random order, the worst case for the table's cache).

use std::hint::black_box;

use bench_support::{CpuTime, clock_prefix};
use criterion::measurement::Measurement;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use tiny_nn::{
    HashGrid, HashGridConfig, Interpolation, Outside, PlaneCombine, Precision, TimeAxis,
    TriPlaneConfig,
};

fn vals(n: usize, seed: u64, s: f32) -> Vec<f32> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1);
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * s
        })
        .collect()
}

fn grid(name: &str, p: Precision) -> HashGrid {
    let cfg = match name {
        "spatial" => HashGridConfig::new(3, 16, 2, 19, 16.0, 2048.0),
        _ => HashGridConfig::new(3, 32, 2, 19, 8.0, 32.0)
            .resolutions(&[8.0, 8.0, 8.0], &[32.0, 32.0, 16.0]),
    };
    cfg.bounds(&[-1.6; 3], &[1.6; 3])
        .interpolation(Interpolation::Smoothstep)
        .outside(Outside::Zero)
        .precision(p)
        .build()
        .unwrap()
}

fn hashgrid_benches<M: Measurement>(c: &mut Criterion<M>) {
    let mut g = c.benchmark_group(format!("{}hashgrid", clock_prefix::<M>()));
    let rows = 100_000;
    let x = vals(rows * 3, 1, 1.5);
    for name in ["spatial", "temporal"] {
        for prec in [Precision::F32, Precision::F16] {
            let enc = grid(name, prec);
            let d = vals(rows * enc.output_width(), 2, 1.0);
            g.throughput(Throughput::Elements(rows as u64));
            g.bench_function(
                BenchmarkId::new(format!("{name}/{prec:?}/fwd"), rows),
                |b| b.iter(|| enc.forward(black_box(&x), rows).unwrap()),
            );
            g.bench_function(
                BenchmarkId::new(format!("{name}/{prec:?}/fwd+bwd"), rows),
                |b| {
                    b.iter(|| {
                        let (_, cache) = enc.forward(black_box(&x), rows).unwrap();
                        enc.backward(&cache, &d, true).unwrap()
                    });
                },
            );
        }
    }
    g.finish();
}

fn hexplane_benches<M: Measurement>(c: &mut Criterion<M>) {
    let mut g = c.benchmark_group(format!("{}hexplane", clock_prefix::<M>()));
    let rows = 100_000;
    let x: Vec<f32> = vals(rows * 4, 3, 1.0)
        .chunks_exact(4)
        .flat_map(|r| [r[0], r[1], r[2], 0.5 + 0.5 * r[3]])
        .collect();
    for prec in [Precision::F32, Precision::F16] {
        let enc = TriPlaneConfig::new(32, &[64, 128], PlaneCombine::Product)
            .time(TimeAxis::new(100, -1.0, 1.0))
            .precision(prec)
            .build()
            .unwrap();
        let d = vals(rows * enc.output_width(), 4, 1.0);
        g.throughput(Throughput::Elements(rows as u64));
        g.bench_function(BenchmarkId::new(format!("{prec:?}/fwd"), rows), |b| {
            b.iter(|| enc.forward(black_box(&x), rows).unwrap());
        });
        g.bench_function(BenchmarkId::new(format!("{prec:?}/fwd+bwd"), rows), |b| {
            b.iter(|| {
                let (_, cache) = enc.forward(black_box(&x), rows).unwrap();
                enc.backward(&cache, &d, true).unwrap()
            });
        });
    }
    g.finish();
}

criterion_group!(benches, hashgrid_benches, hexplane_benches);
criterion_group! {
    name = cpu_benches;
    config = Criterion::default().with_measurement(CpuTime::wall_equivalent());
    targets = hashgrid_benches, hexplane_benches
}
criterion_main!(benches, cpu_benches);
