//! A training step of the evolution state for 100K Gaussians, D = 10: forward with the learned
//! gain (Ψ forward included), losses and backward (Ψ backward included), commit. f32 and f16
//! buffer storage; plus the parts, to show where the time goes.

use bench_support::{CpuTime, clock_prefix};
use criterion::measurement::{Measurement, WallTime};
use criterion::{Criterion, criterion_group, criterion_main};
use evo_state::{EvoConfig, EvoState, Frames, Storage};
use std::hint::black_box;

const N: usize = 100_000;

fn observations(k: usize, d: usize) -> Vec<f32> {
    (0..N * d)
        .map(|e| ((e * 7 + k * 13) % 101) as f32 * 0.01 + k as f32 * 0.05)
        .collect()
}

/// A state with frames 0..3 committed, ready for the learned stage at frame 3.
fn warmed(storage: Storage) -> EvoState {
    let frames = Frames::new((0..10).map(|k| k as f32 / 9.0).collect()).unwrap();
    let config = EvoConfig {
        storage,
        ..EvoConfig::default()
    };
    let mut st = EvoState::new(config, frames, N, 7).unwrap();
    for k in 0..3 {
        let z = observations(k, st.dim());
        let step = st.forward(st.frames().times()[k], &z).unwrap();
        st.commit(&step).unwrap();
    }
    st
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let cpu = !clock_prefix::<M>().is_empty();
    let mut group = c.benchmark_group(if cpu {
        "cpu/evo_state_100k_d10"
    } else {
        "evo_state_100k_d10"
    });
    for (name, storage) in [("f32", Storage::F32), ("f16", Storage::F16)] {
        let mut st = warmed(storage);
        let d = st.dim();
        let t = st.frames().times()[3];
        let z = observations(3, d);
        let dl_dd = vec![1e-6f32; N * d];
        let opacity = vec![0.5f32; N];
        group.bench_function(format!("train_step_{name}"), |b| {
            b.iter(|| {
                let step = st.forward(t, black_box(&z)).unwrap();
                let grads = st.backward(&step, &z, &dl_dd, &opacity).unwrap();
                st.commit(&step).unwrap();
                black_box(grads.dpsi);
            });
        });
        // The same step with a kept Step/Backward whose buffers are reused (a training loop).
        let mut step = evo_state::Step::empty();
        let mut grads = evo_state::Backward::default();
        group.bench_function(format!("train_step_reused_{name}"), |b| {
            b.iter(|| {
                st.forward_into(t, black_box(&z), None, &mut step).unwrap();
                st.backward_into(&step, &z, &dl_dd, &opacity, &mut grads)
                    .unwrap();
                st.commit(&step).unwrap();
                black_box(&grads.dpsi);
            });
        });
        group.bench_function(format!("forward_{name}"), |b| {
            b.iter(|| black_box(st.forward(t, black_box(&z)).unwrap()));
        });
        let step = st.forward(t, &z).unwrap();
        group.bench_function(format!("backward_{name}"), |b| {
            b.iter(|| black_box(st.backward(&step, &z, &dl_dd, &opacity).unwrap()));
        });
        group.bench_function(format!("commit_{name}"), |b| {
            b.iter(|| st.commit(&step).unwrap());
        });
    }
    // Ψ alone (tiny-nn), forward + backward over 100K rows of 13 inputs.
    let st = warmed(Storage::F32);
    let x: Vec<f32> = (0..N * 13).map(|e| (e % 17) as f32 * 0.1 - 0.8).collect();
    let dk = vec![1e-3f32; N];
    group.bench_function("psi_forward_backward", |b| {
        b.iter(|| {
            let (k, cache) = st.psi().forward(black_box(&x), N).unwrap();
            black_box(k);
            black_box(st.psi().backward(&cache, &dk).unwrap())
        });
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
