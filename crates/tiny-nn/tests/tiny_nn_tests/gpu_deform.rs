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
