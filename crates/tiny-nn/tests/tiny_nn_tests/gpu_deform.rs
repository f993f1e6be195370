//! The GPU D-3DGS deformation network (`tiny_nn::gpu::GpuDeformNet`: sinusoidal encoding on the
//! device, then the GPU MLP) against the CPU's [`DeformNet::forward`] and
//! [`DeformNet::backward`]: D-3DGS's own setting and smaller ones, positions in a D-NeRF scene's
//! range and far out (±700, where the highest frequency's argument is about 360 000 and the
//! reduction to [−π, π] must stay exact), times over [0, 1], with and without the positions'
//! gradient.
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

use std::sync::OnceLock;

use gpu_core::GpuContext;
use tiny_nn::gpu::GpuDeformNet;
use tiny_nn::{DeformConfig, DeformNet};

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
