//! Throughput of the networks: gemm peak, EvoGS Φ and the D-3DGS MLP, f32 and f16 storage,
//! forward and forward + backward.
//!
//! Before the timed benches, prints the FLOP count per row and the maximum |f16 - f32| output
//! difference of each network (same f16-representable weights in both, random non-zero output
//! layer so the difference is not trivially 0).

use std::hint::black_box;

use bench_support::{CpuTime, clock_prefix};
use criterion::measurement::Measurement;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use tiny_nn::linalg::{matmul, parallelism};
use tiny_nn::{
    BSplineConfig, DeformConfig, DeformNet, ObservationConfig, ObservationNet, PlaneCombine,
    Precision, TriPlaneConfig,
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

fn phi(p: Precision, combine: PlaneCombine) -> ObservationNet {
    let mut net = ObservationNet::new(ObservationConfig {
        triplane: TriPlaneConfig::new(32, &[64], combine),
        bspline: BSplineConfig::new(16, 16),
        width: 64,
        hidden_layers: 2,
        output: 10,
        precision: p,
        seed: 1,
    })
    .unwrap();
    // A trained-looking (non-zero) output layer, same f16-representable values in both precisions.
    let n = net.mlp.param_count();
    let w: Vec<f32> = net
        .mlp
        .params()
        .to_vec_f32()
        .iter()
        .zip(vals(n, 3, 0.1))
        .map(|(a, b)| tiny_nn::precision::round_to_f16(if *a == 0.0 { b } else { *a }))
        .collect();
    net.mlp.set_params(&w).unwrap();
    net
}

fn deform(p: Precision) -> DeformNet {
    let mut net = DeformNet::new(DeformConfig {
        precision: p,
        ..DeformConfig::d3dgs()
    })
    .unwrap();
    let w: Vec<f32> = net
        .mlp
        .params()
        .to_vec_f32()
        .iter()
        .map(|&a| tiny_nn::precision::round_to_f16(a))
        .collect();
    net.mlp.set_params(&w).unwrap();
    net
}

fn inputs(rows: usize) -> (Vec<f32>, Vec<f32>) {
    let p = vals(rows * 3, 7, 1.0);
    let t: Vec<f32> = vals(rows, 8, 0.5).iter().map(|v| v + 0.5).collect();
    (p, t)
}

fn max_err(a: &[f32], b: &[f32]) -> (f32, f32) {
    let e = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    let s = a.iter().map(|x| x.abs()).fold(0.0, f32::max);
    (e, s)
}

fn report_accuracy() {
    let rows = 10_000;
    let (p, t) = inputs(rows);
    for combine in [PlaneCombine::Product, PlaneCombine::Concat] {
        let (a, _) = phi(Precision::F32, combine).forward(&p, &t, rows).unwrap();
        let (b, _) = phi(Precision::F16, combine).forward(&p, &t, rows).unwrap();
        let (e, s) = max_err(&a, &b);
        eprintln!(
            "phi {combine:?}: {} MAC/row in the decoder; f16 vs f32 max |diff| {e:.3e} (max |out| {s:.3e})",
            phi(Precision::F32, combine).macs_per_row()
        );
    }
    let (a, _) = deform(Precision::F32).forward(&p, &t, rows).unwrap();
    let (b, _) = deform(Precision::F16).forward(&p, &t, rows).unwrap();
    let (e, s) = max_err(&a, &b);
    eprintln!(
        "d3dgs: {} MAC/row; f16 vs f32 max |diff| {e:.3e} (max |out| {s:.3e})",
        deform(Precision::F32).macs_per_row()
    );
}

fn gemm_peak<M: Measurement>(c: &mut Criterion<M>) {
    let n = 1024;
    let a = vals(n * n, 1, 1.0);
    let b = vals(n * n, 2, 1.0);
    let mut out = vec![0f32; n * n];
    let mut g = c.benchmark_group(format!("{}gemm_f32", clock_prefix::<M>()));
    g.throughput(Throughput::Elements((2 * n * n * n) as u64)); // FLOPs
    g.bench_function(BenchmarkId::new("square", n), |bch| {
        bch.iter(|| {
            matmul(
                &mut out,
                black_box(&a),
                black_box(&b),
                (n, n, n),
                false,
                parallelism(rayon::current_num_threads()),
            );
        });
    });
    g.finish();
}

/// Steady state of a training loop: the cache is kept between steps (`forward_into`).
fn phi_benches<M: Measurement>(c: &mut Criterion<M>) {
    let mut g = c.benchmark_group(format!("{}phi", clock_prefix::<M>()));
    for (combine, sizes) in [
        (PlaneCombine::Product, &[10_000usize, 100_000][..]),
        (PlaneCombine::Concat, &[100_000usize][..]),
    ] {
        for &rows in sizes {
            let (p, t) = inputs(rows);
            let d = vals(rows * 10, 9, 1.0);
            g.throughput(Throughput::Elements(rows as u64));
            for prec in [Precision::F32, Precision::F16] {
                let net = phi(prec, combine);
                let (_, mut cache) = net.forward(&p, &t, rows).unwrap();
                let name = format!("{combine:?}/{prec:?}");
                g.bench_function(BenchmarkId::new(format!("{name}/fwd"), rows), |b| {
                    b.iter(|| {
                        net.forward_into(black_box(&p), &t, rows, &mut cache)
                            .unwrap()
                    });
                });
                g.bench_function(BenchmarkId::new(format!("{name}/fwd+bwd"), rows), |b| {
                    b.iter(|| {
                        net.forward_into(black_box(&p), &t, rows, &mut cache)
                            .unwrap();
                        net.backward(&cache, &d, false).unwrap()
                    });
                });
            }
        }
    }
    g.finish();
}

/// The Φ decoder alone (product tri-plane: 32 + 16 inputs → 64 → 64 → 10): the matrix work.
fn decoder_benches<M: Measurement>(c: &mut Criterion<M>) {
    let mut g = c.benchmark_group(format!("{}phi_decoder", clock_prefix::<M>()));
    let rows = 100_000;
    let mlp = phi(Precision::F32, PlaneCombine::Product).mlp;
    let ni = mlp.input_width();
    let x = vals(rows * ni, 4, 1.0);
    let d = vals(rows * 10, 9, 1.0);
    let (_, mut cache) = mlp.forward(&x, rows).unwrap();
    let fill =
        |r0: usize, nr: usize, buf: &mut [f32]| buf.copy_from_slice(&x[r0 * ni..(r0 + nr) * ni]);
    g.throughput(Throughput::Elements(rows as u64));
    g.bench_function(BenchmarkId::new("F32/fwd", rows), |b| {
        b.iter(|| mlp.forward_into(rows, fill, &mut cache));
    });
    g.bench_function(BenchmarkId::new("F32/fwd+bwd(dx)", rows), |b| {
        b.iter(|| {
            mlp.forward_into(rows, fill, &mut cache);
            mlp.backward(&cache, &d, true).unwrap()
        });
    });
    g.finish();
}

fn d3dgs_benches<M: Measurement>(c: &mut Criterion<M>) {
    let mut g = c.benchmark_group(format!("{}d3dgs", clock_prefix::<M>()));
    for rows in [10_000usize, 100_000] {
        let (p, t) = inputs(rows);
        let d = vals(rows * 10, 9, 1.0);
        g.throughput(Throughput::Elements(rows as u64));
        for prec in [Precision::F32, Precision::F16] {
            let net = deform(prec);
            let (_, mut cache) = net.forward(&p, &t, rows).unwrap();
            g.bench_function(BenchmarkId::new(format!("{prec:?}/fwd"), rows), |b| {
                b.iter(|| {
                    net.forward_into(black_box(&p), &t, rows, &mut cache)
                        .unwrap()
                });
            });
            g.bench_function(BenchmarkId::new(format!("{prec:?}/fwd+bwd"), rows), |b| {
                b.iter(|| {
                    net.forward_into(black_box(&p), &t, rows, &mut cache)
                        .unwrap();
                    net.backward(&cache, &d, false).unwrap()
                });
            });
        }
    }
    g.finish();
}

fn accuracy(_: &mut Criterion) {
    report_accuracy();
}

criterion_group!(
    benches,
    accuracy,
    gemm_peak,
    decoder_benches,
    phi_benches,
    d3dgs_benches
);
criterion_group! {
    name = cpu_benches;
    config = Criterion::default().with_measurement(CpuTime::wall_equivalent());
    targets = gemm_peak, decoder_benches, phi_benches, d3dgs_benches
}
criterion_main!(benches, cpu_benches);
