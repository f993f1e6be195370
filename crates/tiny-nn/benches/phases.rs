//! Where Φ's decoder spends its time: each product shape of one row block, single-threaded, and
//! the element-wise passes around them. CPU time of the process (one thread busy), so the
//! figures are per-core and comparable with the single-thread gemm peak measured here too.

use std::hint::black_box;

use bench_support::CpuTime;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use gemm::Parallelism;
use tiny_nn::linalg::{matmul, matmul_a_bt, matmul_at_b};

fn vals(n: usize, seed: u64) -> Vec<f32> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(1);
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        })
        .collect()
}

type Product = fn(&mut [f32], &[f32], &[f32], (usize, usize, usize), bool, Parallelism);
/// Name, product, (m, k, n), accumulate.
type Shape = (&'static str, Product, (usize, usize, usize), bool);

fn products(c: &mut Criterion<CpuTime>) {
    let mut g = c.benchmark_group("phases/product");
    // Forward blocks are `mlp::ROW_BLOCK` = 256 rows, backward blocks `BACKWARD_BLOCK` = 1024.
    let (nf, nr) = (tiny_nn::mlp::ROW_BLOCK, tiny_nn::mlp::BACKWARD_BLOCK);
    let shapes: [Shape; 10] = [
        ("peak_256cube", matmul, (256, 256, 256), false),
        ("fwd_l0_x.W", matmul, (nf, 48, 64), false),
        ("fwd_l1_x.W", matmul, (nf, 64, 64), false),
        ("fwd_l2_x.W", matmul, (nf, 64, 10), false),
        ("dW_l0_xT.g", matmul_at_b, (48, nr, 64), true),
        ("dW_l1_xT.g", matmul_at_b, (64, nr, 64), true),
        ("dW_l2_xT.g", matmul_at_b, (64, nr, 10), true),
        ("dx_l0_g.WT", matmul_a_bt, (nr, 64, 48), false),
        ("dx_l1_g.WT", matmul_a_bt, (nr, 64, 64), false),
        ("dx_l2_g.WT", matmul_a_bt, (nr, 10, 64), false),
    ];
    for (name, f, (m, k, n), acc) in shapes {
        let a = vals(m * k, 1);
        let b = vals(k * n, 2);
        let mut out = vec![0f32; m * n];
        g.throughput(Throughput::Elements((2 * m * k * n) as u64));
        g.bench_function(BenchmarkId::new(name, format!("{m}x{k}x{n}")), |bch| {
            bch.iter(|| {
                f(
                    &mut out,
                    black_box(&a),
                    black_box(&b),
                    (m, k, n),
                    acc,
                    Parallelism::None,
                );
            });
        });
    }
    g.finish();
}

/// The decoder 48 → 64 → 64 → 10 on one thread: per-row cost with a hot block (1024 rows, all in
/// L2) against the full 100K rows.
fn decoder(c: &mut Criterion<CpuTime>) {
    let mut g = c.benchmark_group("phases/decoder1t");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mlp = tiny_nn::MlpConfig::new(48, 64, 2, 10)
        .seed(3)
        .build()
        .unwrap();
    for rows in [1024usize, 100_000] {
        let x = vals(rows * 48, 4);
        let d = vals(rows * 10, 9);
        let (_, mut cache) = mlp.forward(&x, rows).unwrap();
        let fill = |r0: usize, nr: usize, buf: &mut [f32]| {
            buf.copy_from_slice(&x[r0 * 48..(r0 + nr) * 48]);
        };
        g.throughput(Throughput::Elements(rows as u64));
        g.bench_function(BenchmarkId::new("fwd", rows), |b| {
            b.iter(|| pool.install(|| mlp.forward_into(rows, fill, &mut cache)));
        });
        g.bench_function(BenchmarkId::new("bwd_with_dx", rows), |b| {
            b.iter(|| pool.install(|| mlp.backward(&cache, &d, true).unwrap()));
        });
        g.bench_function(BenchmarkId::new("bwd_no_dx", rows), |b| {
            b.iter(|| pool.install(|| mlp.backward(&cache, &d, false).unwrap()));
        });
    }
    g.finish();
}

/// Φ (product tri-plane C = 32 at 64², B-spline 16 × 16, decoder 48 → 64 → 64 → 10) over 100K
/// rows with all threads: forward, and backward alone (from a kept cache).
fn phi(c: &mut Criterion<CpuTime>) {
    let rows = 100_000;
    let net = tiny_nn::ObservationNet::new(tiny_nn::ObservationConfig {
        triplane: tiny_nn::TriPlaneConfig::new(32, &[64], tiny_nn::PlaneCombine::Product),
        bspline: tiny_nn::BSplineConfig::new(16, 16),
        width: 64,
        hidden_layers: 2,
        output: 10,
        precision: tiny_nn::Precision::F32,
        seed: 1,
    })
    .unwrap();
    let t: Vec<f32> = vals(rows, 8).iter().map(|v| v * 0.5 + 0.5).collect();
    phi_passes(c, "phases/phi", &net, &t, false);
}

/// Φ's forward, and its backward alone (from a kept cache), over one row per time in `t`
/// (positions from a fixed sequence), with all threads.
fn phi_passes(
    c: &mut Criterion<CpuTime>,
    group: &str,
    net: &tiny_nn::ObservationNet,
    t: &[f32],
    want_position_grad: bool,
) {
    let mut g = c.benchmark_group(group);
    let rows = t.len();
    let p = vals(rows * 3, 7);
    let d = vals(rows * net.mlp.output_width(), 9);
    let (_, mut cache) = net.forward(&p, t, rows).unwrap();
    g.throughput(Throughput::Elements(rows as u64));
    g.bench_function(BenchmarkId::new("fwd", rows), |b| {
        b.iter(|| net.forward_into(&p, t, rows, &mut cache).unwrap());
    });
    g.bench_function(BenchmarkId::new("bwd", rows), |b| {
        b.iter(|| net.backward(&cache, &d, want_position_grad).unwrap());
    });
    g.finish();
}

/// The trainer's Φ (`EvoSettings::default` at network width 64: concatenated tri-plane C = 8 at
/// 32² and 64², B-spline 16 × 8, decoder 56 → 32 → 32 → 10) over 30 000 rows, all at one time
/// as in a training step, with all threads: forward, and backward alone (from a kept cache).
fn phi_trainer(c: &mut Criterion<CpuTime>) {
    let mut triplane = tiny_nn::TriPlaneConfig::new(8, &[32, 64], tiny_nn::PlaneCombine::Concat);
    triplane.box_min = [-1.3; 3];
    triplane.box_max = [1.3; 3];
    let net = tiny_nn::ObservationNet::new(tiny_nn::ObservationConfig {
        triplane,
        bspline: tiny_nn::BSplineConfig::new(16, 8),
        width: 32,
        hidden_layers: 2,
        output: 10,
        precision: tiny_nn::Precision::F32,
        seed: 1,
    })
    .unwrap();
    phi_passes(c, "phases/phi_trainer", &net, &[0.37; 30_000], true);
}

/// One Adam step of an f32 group the size of a lego run's Gaussian parameters (30 000
/// Gaussians of 59 numbers: position, scale, rotation, opacity and degree-3 SH).
fn adam(c: &mut Criterion<CpuTime>) {
    let mut g = c.benchmark_group("phases/adam");
    let n = 30_000 * 59;
    let mut adam = tiny_nn::Adam::new();
    let id = adam
        .add_group("gaussians", n, 59, tiny_nn::LrSchedule::Constant(1e-3))
        .unwrap();
    let mut params = vals(n, 10);
    let grads = vals(n, 11);
    g.throughput(Throughput::Elements(n as u64));
    let mut it = 0;
    g.bench_function(BenchmarkId::new("step_f32", n), |b| {
        b.iter(|| {
            it += 1;
            adam.step(id, it, tiny_nn::StoreMut::F32(&mut params), &grads)
                .unwrap()
        });
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime::total());
    targets = products, decoder, phi, phi_trainer, adam
}
criterion_main!(benches);
