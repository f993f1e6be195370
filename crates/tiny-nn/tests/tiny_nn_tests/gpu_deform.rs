//! The GPU D-3DGS deformation network (`tiny_nn::gpu::GpuDeformNet`: sinusoidal encoding on the
//! device, then the GPU MLP) against the CPU's [`DeformNet::forward`] and
//! [`DeformNet::backward`]: D-3DGS's own setting and smaller ones, positions in a D-NeRF scene's
//! range and far out (±700, where the highest frequency's argument is about 360 000 and the
//! reduction to [−π, π] must stay exact), times over [0, 1], with and without the positions'
//! gradient; and [`DeformRunner`], the same network for callers on the host (the trainer's
//! D-3DGS backbone), as its parameters and row count change, with its input errors and the
//! bytes it moves.
//!
//! Tolerances: outputs and the MLP's gradient within `2e-5 · (|c| + s)` of the CPU's `c`, `s`
//! the root mean square of the compared array (the MLP's own rounding, `gpu_mlp.rs`, plus the
//! encoding's: WGSL's `sin` and `cos` on [−π, π] against Rust's correctly reduced `sin_cos`, a
//! few 1e-7 on lavapipe); the positions' gradient within `1e-5 · (|c| + s)`: it sums the
//! encoding's gradient multiplied by up to 2⁹, which also multiplies the rounding differences
//! of the MLP's input gradient, but those are far smaller than its largest terms. Measured on
//! lavapipe: at most a quarter of the tolerance (the MLP gradient on D-3DGS's setting), an
//! eighth for the positions' gradient. A missing adapter fails these tests (CI pins lavapipe);
//! it is not a skip.

use std::sync::{Arc, OnceLock};

use gpu_core::GpuContext;
use tiny_nn::gpu::{DeformRunner, GpuDeformNet};
use tiny_nn::{DeformConfig, DeformNet, StoreMut};

fn gpu() -> &'static (GpuContext, GpuDeformNet) {
    static GPU: OnceLock<(GpuContext, GpuDeformNet)> = OnceLock::new();
    GPU.get_or_init(|| {
        let ctx = GpuContext::new().unwrap_or_else(|e| {
            panic!("the GPU deformation network needs an adapter (CI installs lavapipe): {e}")
        });
        let net = GpuDeformNet::new(&ctx).unwrap();
        (ctx, net)
    })
}

fn values(seed: u64, n: usize, lo: f32, hi: f32) -> Vec<f32> {
    let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            lo + (hi - lo) * ((x >> 40) as f32 / (1u64 << 24) as f32)
        })
        .collect()
}

fn close(what: &str, gpu: &[f32], cpu: &[f32], rel: f32) {
    assert_eq!(gpu.len(), cpu.len(), "{what}: lengths");
    let s = (cpu.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / cpu.len().max(1) as f64)
        .sqrt() as f32;
    for (i, (&g, &c)) in gpu.iter().zip(cpu).enumerate() {
        let tol = rel * (c.abs() + s);
        assert!(
            (g - c).abs() <= tol,
            "{what}[{i}]: gpu {g} vs cpu {c} (tolerance {tol}, rms {s})"
        );
    }
}

fn compare(config: DeformConfig, rows: usize, seed: u64, extent: f32, want_positions: bool) {
    let (ctx, kernel) = gpu();
    let net = DeformNet::new(config).unwrap();
    let positions = values(seed, rows * 3, -extent, extent);
    let times = values(seed ^ 1, rows, 0.0, 1.0);
    let d_out = values(seed ^ 2, rows * DeformNet::OUTPUT, -1.0, 1.0);
    let (y_cpu, cache) = net.forward(&positions, &times, rows).unwrap();
    let g_cpu = net.backward(&cache, &d_out, want_positions).unwrap();
    let (y_gpu, g_gpu) = kernel
        .forward_backward(ctx, &net, &positions, &times, rows, &d_out, want_positions)
        .unwrap();
    let what = format!("width {} extent {extent}", config.width);
    close(&format!("{what} outputs"), &y_gpu, &y_cpu, 2e-5);
    close(
        &format!("{what} MLP gradient"),
        &g_gpu.mlp,
        &g_cpu.mlp,
        2e-5,
    );
    match (&g_gpu.positions, &g_cpu.positions) {
        (Some(g), Some(c)) => close(&format!("{what} position gradient"), g, c, 1e-5),
        (None, None) => {}
        _ => panic!("{what}: the position gradient on one side only"),
    }
}

fn small(seed: u64) -> DeformConfig {
    DeformConfig {
        width: 32,
        depth: 3,
        skip_after: Some(1),
        seed,
        ..DeformConfig::d3dgs()
    }
}

#[test]
fn gpu_deformation_matches_the_cpu_on_d3dgs_setting() {
    compare(DeformConfig::d3dgs(), 200, 3, 1.5, true);
}

#[test]
fn gpu_deformation_matches_the_cpu_on_small_networks() {
    for (rows, seed, want) in [(1, 1, true), (300, 2, false), (1_500, 3, true)] {
        compare(small(seed), rows, seed, 1.5, want);
    }
    // Ten time frequencies (D-3DGS's real scenes) and no skip.
    let config = DeformConfig {
        t_freqs: 10,
        skip_after: None,
        ..small(4)
    };
    compare(config, 257, 4, 3.0, true);
}

#[test]
fn gpu_deformation_reduces_large_arguments_exactly() {
    compare(small(5), 400, 5, 700.0, true);
}

/// A context of the test's own (the runner holds an `Arc`; the traffic counts are per context,
/// and tests run in parallel).
fn runner_context() -> Arc<GpuContext> {
    Arc::new(GpuContext::new().unwrap_or_else(|e| {
        panic!("the GPU deformation runner needs an adapter (CI installs lavapipe): {e}")
    }))
}

/// Moves every parameter a little, as an optimiser step would.
fn nudge(net: &mut DeformNet, step: usize) {
    let StoreMut::F32(params) = net.mlp.params_mut() else {
        panic!("an f32 network");
    };
    for (i, p) in params.iter_mut().enumerate() {
        *p += 0.01 * (((i * 7_919 + step) % 13) as f32 - 6.0);
    }
}

#[test]
fn the_runner_matches_the_cpu_as_parameters_and_rows_change() {
    let mut runner = DeformRunner::new(runner_context()).unwrap();
    let mut net = DeformNet::new(small(7)).unwrap();
    let mut out = Vec::new();
    // The same rows twice (the parameters written over the device's), then fewer rows (a new
    // workspace, as after densification), each after an optimiser-like change.
    for (step, rows) in [(0, 300), (1, 300), (2, 41)] {
        if step > 0 {
            nudge(&mut net, step);
        }
        let seed = 10 + step as u64;
        let positions = values(seed, rows * 3, -1.5, 1.5);
        let times = values(seed ^ 1, rows, 0.0, 1.0);
        let d_out = values(seed ^ 2, rows * DeformNet::OUTPUT, -1.0, 1.0);
        runner
            .forward_into(&net, &positions, &times, rows, true, &mut out)
            .unwrap();
        let g_gpu = runner.backward(&d_out).unwrap();
        let (y_cpu, cache) = net.forward(&positions, &times, rows).unwrap();
        let g_cpu = net.backward(&cache, &d_out, false).unwrap();
        close(&format!("step {step} outputs"), &out, &y_cpu, 2e-5);
        close(
            &format!("step {step} MLP gradient"),
            &g_gpu,
            &g_cpu.mlp,
            2e-5,
        );
    }
    // A network of another shape is uploaded afresh.
    let other = DeformNet::new(DeformConfig {
        width: 16,
        ..small(8)
    })
    .unwrap();
    let positions = values(20, 30 * 3, -1.5, 1.5);
    let times = values(21, 30, 0.0, 1.0);
    runner
        .forward_into(&other, &positions, &times, 30, false, &mut out)
        .unwrap();
    let (y_cpu, _) = other.forward(&positions, &times, 30).unwrap();
    close("another shape's outputs", &out, &y_cpu, 2e-5);
    // That forward was not a training one: there is nothing to go back through.
    let d_out = vec![1.0; 30 * DeformNet::OUTPUT];
    assert!(runner.backward(&d_out).is_err());
    // No rows: no output and a zero gradient of the network's size.
    runner
        .forward_into(&other, &[], &[], 0, true, &mut out)
        .unwrap();
    assert!(out.is_empty());
    let g = runner.backward(&[]).unwrap();
    assert_eq!(g.len(), other.mlp.param_count());
    assert!(g.iter().all(|&v| v == 0.0));
}

#[test]
fn the_runner_refuses_what_the_cpu_refuses_and_counts_what_it_moves() {
    let mut runner = DeformRunner::new(runner_context()).unwrap();
    let net = DeformNet::new(small(9)).unwrap();
    let rows = 50;
    let mut positions = values(30, rows * 3, -1.5, 1.5);
    let times = values(31, rows, 0.0, 1.0);
    let mut out = Vec::new();
    // Non-finite positions and wrong lengths: the CPU's own messages.
    positions[3 * 17 + 1] = f32::NAN;
    let gpu_err = runner
        .forward_into(&net, &positions, &times, rows, true, &mut out)
        .unwrap_err();
    let cpu_err = net.forward(&positions, &times, rows).unwrap_err();
    assert_eq!(gpu_err.to_string(), cpu_err.to_string());
    assert!(gpu_err.to_string().contains("row 17"), "{gpu_err}");
    positions[3 * 17 + 1] = 0.5;
    let gpu_err = runner
        .forward_into(&net, &positions, &times[1..], rows, true, &mut out)
        .unwrap_err();
    let cpu_err = net.forward(&positions, &times[1..], rows).unwrap_err();
    assert_eq!(gpu_err.to_string(), cpu_err.to_string());
    // A refused forward leaves nothing to go back through.
    assert!(runner.backward(&vec![0.0; rows * 10]).is_err());
    // Once the buffers exist, a forward and backward move exactly the parameters, positions,
    // times and output gradient up, and the rows and the parameter gradient down.
    let d_out = values(32, rows * DeformNet::OUTPUT, -1.0, 1.0);
    runner
        .forward_into(&net, &positions, &times, rows, true, &mut out)
        .unwrap();
    runner.backward(&d_out).unwrap();
    let before = runner.context().traffic();
    runner
        .forward_into(&net, &positions, &times, rows, true, &mut out)
        .unwrap();
    assert!(runner.backward(&d_out[1..]).is_err(), "a short gradient");
    runner.backward(&d_out).unwrap();
    let after = runner.context().traffic();
    let (params, outputs) = (net.mlp.param_count() as u64, DeformNet::OUTPUT as u64);
    let rows = rows as u64;
    assert_eq!(
        after.bytes_up - before.bytes_up,
        4 * (params + 3 * rows + rows + outputs * rows)
    );
    assert_eq!(
        after.bytes_down - before.bytes_down,
        4 * (outputs * rows + params)
    );
    assert_eq!(after.waits - before.waits, 2, "one wait per pass");
}

/// Root mean square.
fn rms(values: &[f32]) -> f32 {
    (values.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / values.len().max(1) as f64).sqrt()
        as f32
}

/// The parameters of an f32 network.
fn params_of(net: &DeformNet) -> Vec<f32> {
    match net.mlp.params() {
        tiny_nn::StoreRef::F32(p) => p.to_vec(),
        tiny_nn::StoreRef::F16(_) => panic!("an f32 network"),
    }
}

/// The resident runner (gradient, Adam and moments on the device) against the CPU's backward and
/// Adam, each step from the same state (the CPU takes the device's parameters and moments, read
/// back, before its step): rows, then the same rows, then none (a zero gradient).
///
/// Tolerances, from the gradient's (`2e-5 · (|g| + s)`, above, `s` its root mean square):
/// `m = β1 m' + (1 − β1) g` within `(1 − β1) Δ`, `v` within `(1 − β2)(2|g| + Δ) Δ`, `Δ` that
/// bound on `g`'s, plus f32 rounding; a parameter moves by `lr · m̂ / (√v̂ + ε)`, whose
/// difference is at most about `0.75 lr · Δ / |g|` (√v̂ ≥ |g| / √2 after two steps, m̂'s share
/// of g is (1 − β1) / (1 − β1²)), under `2e-3 lr` where `|g| ≥ 1 %` of `s`; below that the
/// first step's `±lr` may take the other sign, `2 lr` apart.
#[test]
fn the_resident_runner_steps_like_the_hosts_adam_and_moves_only_the_rows() {
    use tiny_nn::{Adam, LrSchedule};
    let mut runner = DeformRunner::new(runner_context()).unwrap();
    let (mut cpu, mut gpu) = (
        DeformNet::new(small(11)).unwrap(),
        DeformNet::new(small(11)).unwrap(),
    );
    let lr = 1e-3;
    let count = cpu.mlp.param_count();
    let (mut adam_cpu, mut adam_gpu) = (Adam::new(), Adam::new());
    let id = adam_cpu
        .add_group("net", count, 1, LrSchedule::Constant(lr))
        .unwrap();
    adam_gpu
        .add_group("net", count, 1, LrSchedule::Constant(lr))
        .unwrap();
    assert!(!runner.resident());
    let mut out = Vec::new();
    let mut flips = 0;
    for (step, rows) in [(0, 200), (1, 200), (2, 0)] {
        let seed = 40 + step as u64;
        let positions = values(seed, rows * 3, -1.5, 1.5);
        let times = values(seed ^ 1, rows, 0.0, 1.0);
        let d_out = values(seed ^ 2, rows * DeformNet::OUTPUT, -1.0, 1.0);
        // The CPU from the device's state.
        let before = params_of(&gpu);
        if let StoreMut::F32(p) = cpu.mlp.params_mut() {
            p.copy_from_slice(&before);
        }
        *adam_cpu.group_mut(id) = adam_gpu.group(id).clone();
        let (y_cpu, cache) = cpu.forward(&positions, &times, rows).unwrap();
        let g = cpu.backward(&cache, &d_out, false).unwrap().mlp;
        adam_cpu.step(id, step, cpu.mlp.params_mut(), &g).unwrap();
        runner
            .forward_into(&gpu, &positions, &times, rows, true, &mut out)
            .unwrap();
        close(&format!("step {step} outputs"), &out, &y_cpu, 2e-5);
        runner.backward_on_device(&d_out).unwrap();
        let update = adam_gpu.next_update(id, step).unwrap();
        runner.step(&update, adam_gpu.group(id)).unwrap();
        assert!(runner.resident());
        runner
            .read_to_host(&mut gpu, adam_gpu.group_mut(id))
            .unwrap();

        let (c, d) = (adam_cpu.group(id), adam_gpu.group(id));
        assert_eq!(c.step, d.step);
        let s = rms(&g);
        let (b1, b2) = (0.9f32, 0.999f32);
        let after = params_of(&cpu);
        let on_device = params_of(&gpu);
        for i in 0..count {
            let delta = 2e-5 * (g[i].abs() + s);
            let tol_m = (1.0 - b1) * delta + 1e-6 * c.m[i].abs();
            assert!(
                (d.m[i] - c.m[i]).abs() <= tol_m,
                "step {step} m[{i}]: {} vs {} (±{tol_m})",
                d.m[i],
                c.m[i]
            );
            let tol_v = (1.0 - b2) * (2.0 * g[i].abs() + delta) * delta + 1e-6 * c.v[i];
            assert!(
                (d.v[i] - c.v[i]).abs() <= tol_v,
                "step {step} v[{i}]: {} vs {} (±{tol_v})",
                d.v[i],
                c.v[i]
            );
            let close_enough = 2e-3 * lr + 1e-6 * after[i].abs();
            let tol_p = if g[i].abs() >= 0.01 * s {
                close_enough
            } else {
                flips += usize::from((on_device[i] - after[i]).abs() > close_enough);
                2.0 * lr + 1e-6 * after[i].abs()
            };
            assert!(
                (on_device[i] - after[i]).abs() <= tol_p,
                "step {step} parameter {i}: {} vs {} (±{tol_p}, from {})",
                on_device[i],
                after[i],
                before[i]
            );
        }
        // The step moved the parameters (the zero gradient too: Adam's momentum).
        assert!(on_device != before, "step {step} left the parameters");
    }
    eprintln!("resident steps: {flips} of {count} parameters took the other sign");
    assert!(flips * 100 <= count, "{flips} of {count} flipped");

    // Resident, an iteration moves the positions, times and output gradient up with the step's
    // constants, and the rows down: no parameter, no gradient, one wait.
    let rows = 120;
    let positions = values(60, rows * 3, -1.5, 1.5);
    let times = values(61, rows, 0.0, 1.0);
    let d_out = values(62, rows * DeformNet::OUTPUT, -1.0, 1.0);
    let iteration = |runner: &mut DeformRunner, adam: &mut Adam, out: &mut Vec<f32>| {
        runner
            .forward_into(&gpu, &positions, &times, rows, true, out)
            .unwrap();
        runner.backward_on_device(&d_out).unwrap();
        let update = adam.next_update(id, 5).unwrap();
        runner.step(&update, adam.group(id)).unwrap();
    };
    iteration(&mut runner, &mut adam_gpu, &mut out);
    let before = runner.context().traffic();
    iteration(&mut runner, &mut adam_gpu, &mut out);
    let moved = runner.context().traffic().since(&before);
    let (outputs, rows) = (DeformNet::OUTPUT as u64, rows as u64);
    let constants = 48;
    assert_eq!(
        moved.bytes_up,
        4 * (3 * rows + rows + outputs * rows) + constants
    );
    assert_eq!(moved.bytes_down, 4 * outputs * rows);
    assert_eq!(moved.waits, 1, "the rows' read-back only");
    // Resident, the host's way is refused rather than mixed in, and forget hands the truth back.
    runner
        .forward_into(&gpu, &positions, &times, rows as usize, true, &mut out)
        .unwrap();
    assert!(runner.backward(&d_out).is_err());
    runner.forget();
    assert!(!runner.resident());
    runner
        .forward_into(&gpu, &positions, &times, rows as usize, true, &mut out)
        .unwrap();
    assert_eq!(runner.backward(&d_out).unwrap().len(), count);
    // A step without a backward on the device is refused.
    assert!(
        runner
            .step(&adam_gpu.next_update(id, 6).unwrap(), adam_gpu.group(id))
            .is_err()
    );
}
