//! SC-GS's backbone by part, at 512 control points and 10 000 or 40 000 Gaussians spread over
//! a lego-sized cube: the K = 3 nearest search (kiddo), the skinning forward and backward (and
//! their plain per-pair twins of `skinning::reference`), the
//! control-point network's forward and backward (SC-GS's 256 × 8, and 128 × 8), and a whole
//! backbone step (forward + backward) with and without the ARAP term.
//!
//! Measured with `CpuTime::wall_equivalent` (process CPU time over rayon's threads): the machine
//! is shared.

use bench_support::{CpuTime, clock_prefix};
use criterion::measurement::Measurement;
use criterion::{Criterion, criterion_group, criterion_main};
use evogs_backbones::scgs::knn;
use evogs_backbones::scgs::skinning::{
    Controls, NODE_OUTPUT, ROW, reference, skin_backward, skin_into,
};
use evogs_backbones::{Backbone, ScgsBackbone, ScgsSettings};
use splat_core::Gaussians;

/// Points in `[-h, h]³` from a small deterministic generator.
fn cloud(n: usize, h: f32, seed: u64) -> Vec<[f32; 3]> {
    let mut s = seed;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * h
    };
    (0..n).map(|_| [next(), next(), next()]).collect()
}

fn gaussians(n: usize) -> Gaussians {
    let mut g = Gaussians::with_degree(0);
    for p in cloud(n, 1.0, 3) {
        g.means.push(p);
        g.log_scales.push([-4.0; 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(0.0);
        g.sh.extend([0.1, 0.2, 0.3]);
    }
    g
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let mut group = c.benchmark_group(format!("{}scgs_512_controls", clock_prefix::<M>()));
    group.sample_size(10);
    let m = 512;
    let controls = cloud(m, 1.0, 7);
    let log_radii = vec![(0.2f32).ln(); m];
    let weight_logits = vec![0.0; m];
    let nodes: Vec<f32> = cloud(m * NODE_OUTPUT / 3 + 1, 0.05, 9)
        .into_iter()
        .flatten()
        .take(m * NODE_OUTPUT)
        .collect();
    let shape = Controls {
        positions: &controls,
        log_radii: &log_radii,
        weight_logits: &weight_logits,
    };
    for n in [10_000, 40_000] {
        let g = gaussians(n);
        group.bench_function(format!("knn_k3/{n}"), |b| {
            b.iter(|| knn::nearest(&controls, &g.means, 3).unwrap());
        });
        let nb = knn::nearest(&controls, &g.means, 3).unwrap();
        let mut rows = Vec::new();
        group.bench_function(format!("skin_forward/{n}"), |b| {
            b.iter(|| skin_into(&g.means, &nb, shape, &nodes, &mut rows));
        });
        group.bench_function(format!("skin_forward_plain/{n}"), |b| {
            b.iter(|| reference::skin_into(&g.means, &nb, shape, &nodes, &mut rows));
        });
        let d_rows = vec![1e-3f32; n * ROW];
        group.bench_function(format!("skin_backward/{n}"), |b| {
            b.iter(|| skin_backward(&g.means, &nb, shape, &nodes, &d_rows));
        });
        group.bench_function(format!("skin_backward_plain/{n}"), |b| {
            b.iter(|| reference::skin_backward(&g.means, &nb, shape, &nodes, &d_rows));
        });
        for (width, arap) in [(256, 1e-4), (256, 0.0), (128, 1e-4), (64, 1e-4)] {
            let settings = ScgsSettings {
                width,
                arap_weight: arap,
                ..ScgsSettings::default()
            };
            let mut backbone = ScgsBackbone::new(&settings, 1.3, 1).unwrap();
            backbone.initialise(g.view()).unwrap();
            let mut out = Vec::new();
            let mut grads = Vec::new();
            group.bench_function(
                format!("backbone_step_width{width}_arap{}/{n}", arap > 0.0),
                |b| {
                    b.iter(|| {
                        backbone
                            .forward_into(g.view(), 0.4, true, &mut out)
                            .unwrap();
                        backbone.backward_into(&d_rows, &mut grads).unwrap();
                    });
                },
            );
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(CpuTime::wall_equivalent());
    targets = bench::<CpuTime>
}
criterion_main!(benches);
