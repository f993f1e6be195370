//! The GPU Adam step (`tiny_nn::gpu::GpuAdam`) against the CPU's [`Adam::step`] and
//! [`Adam::step_columns`]: several steps of a 3DGS exponential schedule on random groups of many
//! lengths, column ranges of wider rows (3DGS's `f_dc` / `f_rest`), and the hard cases (zero,
//! huge, tiny and non-finite gradients, a group of no values).
//!
//! Tolerances: after every step each parameter within `2e-6 · |Δθ| + 2 ulp(θ)` of the CPU's
//! (`Δθ` the CPU's step, `2 ulp(θ)` taken as `2.4e-7 · |θ|`), each moment within `1e-6 · |m|`
//! (`|v|`) plus 1e-37. WGSL allows 2.5 ulp for a division and about 2 for a square root, and a
//! driver may fuse a product and a sum into one fused multiply-add: a step's value may differ by
//! a few ulp of the step (2e-6 is about 16), and after the subtraction by one more rounding of
//! the parameter. The moments are products and sums only (one
//! rounding each, fused or not), so 1e-6 (8 ulp) leaves room for the same differences carried
//! over five steps; below 1e-37 a device may flush subnormal values to zero. A missing adapter
//! fails these tests (CI pins lavapipe); it is not a skip.

use std::sync::OnceLock;

use gpu_core::GpuContext;
use proptest::prelude::*;
use tiny_nn::gpu::GpuAdam;
use tiny_nn::{Adam, ExponentialLr, LrSchedule};

fn gpu() -> &'static (GpuContext, GpuAdam) {
    static GPU: OnceLock<(GpuContext, GpuAdam)> = OnceLock::new();
    GPU.get_or_init(|| {
        let ctx = GpuContext::new().unwrap_or_else(|e| {
            panic!("the GPU Adam needs an adapter (CI installs lavapipe): {e}")
        });
        let adam = GpuAdam::new(&ctx).unwrap();
        (ctx, adam)
    })
}

/// 3DGS's position schedule (lr 1.6e-4 → 1.6e-6), scaled.
fn schedule(scale: f32) -> LrSchedule {
    LrSchedule::Exponential(ExponentialLr {
        lr_init: 1.6e-4 * scale,
        lr_final: 1.6e-6 * scale,
        delay_steps: 0,
        delay_mult: 1.0,
        max_steps: 30_000,
    })
}

fn close(what: &str, gpu: &[f32], cpu: &[f32], tol: impl Fn(usize) -> f32) {
    assert_eq!(gpu.len(), cpu.len(), "{what}: lengths");
    for (i, (&g, &c)) in gpu.iter().zip(cpu).enumerate() {
        let same = g == c || (g.is_nan() && c.is_nan());
        assert!(
            same || (g - c).abs() <= tol(i),
            "{what}[{i}]: gpu {g} vs cpu {c} (tolerance {})",
            tol(i)
        );
    }
}

/// Runs `steps` updates of one group on both, with the gradients `grads(step)`, comparing
/// parameters and moments after each; `cols` as `(stride, range)` for a column group.
fn compare(
    params: Vec<f32>,
    grads: impl Fn(usize) -> Vec<f32>,
    steps: usize,
    cols: Option<(usize, std::ops::Range<usize>)>,
) {
    let (ctx, kernel) = gpu();
    let (len, width) = match &cols {
        Some((stride, r)) => (params.len() / stride * r.len(), r.len()),
        None => (params.len(), 1),
    };
    let mut cpu = Adam::new();
    let id = cpu
        .add_group("g", len, width.max(1), schedule(1.0))
        .unwrap();
    let mut gpu_adam = cpu.clone();
    let (mut p_cpu, mut p_gpu) = (params.clone(), params);
    for s in 0..steps {
        let g = grads(s);
        let before = p_cpu.clone();
        let it = 100 * s as i64;
        match &cols {
            Some((stride, r)) => {
                cpu.step_columns(id, it, &mut p_cpu, &g, *stride, r.clone())
                    .unwrap();
                kernel
                    .step_columns(
                        ctx,
                        &mut gpu_adam,
                        id,
                        it,
                        &mut p_gpu,
                        &g,
                        *stride,
                        r.clone(),
                    )
                    .unwrap();
            }
            None => {
                cpu.step(id, it, tiny_nn::StoreMut::F32(&mut p_cpu), &g)
                    .unwrap();
                kernel
                    .step(ctx, &mut gpu_adam, id, it, &mut p_gpu, &g)
                    .unwrap();
            }
        }
        let what = format!("step {s}");
        close(&format!("{what} params"), &p_gpu, &p_cpu, |i| {
            2e-6 * (before[i] - p_cpu[i]).abs() + 2.4e-7 * before[i].abs().max(p_cpu[i].abs())
        });
        let (gc, gg) = (cpu.group(id), gpu_adam.group(id));
        assert_eq!(gc.step, gg.step, "{what}: step counts");
        close(&format!("{what} m"), &gg.m, &gc.m, |i| {
            1e-6 * gc.m[i].abs() + 1e-37
        });
        close(&format!("{what} v"), &gg.v, &gc.v, |i| {
            1e-6 * gc.v[i].abs() + 1e-37
        });
    }
}

fn values(seed: u64, n: usize, scale: f32) -> Vec<f32> {
    let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * scale
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    #[test]
    fn gpu_adam_matches_the_cpu_step(len in 1usize..5_000, seed in any::<u64>(), decade in -6i32..3) {
        let scale = 10f32.powi(decade);
        compare(
            values(seed, len, 1.0),
            |s| values(seed ^ (s as u64 + 1), len, scale),
            5,
            None,
        );
    }

    #[test]
    fn gpu_adam_matches_the_cpu_step_on_columns(
        rows in 1usize..700,
        stride in 1usize..12,
        start_frac in 0.0f64..1.0,
        seed in any::<u64>(),
    ) {
        let start = ((stride as f64 * start_frac) as usize).min(stride - 1);
        let end = start + 1 + (seed as usize % (stride - start));
        compare(
            values(seed, rows * stride, 1.0),
            |s| values(seed ^ (s as u64 + 7), rows * stride, 0.1),
            4,
            Some((stride, start..end)),
        );
    }
}

#[test]
fn gpu_adam_matches_the_cpu_step_in_hard_cases() {
    let n = 64;
    let hard = |s: usize| -> Vec<f32> {
        (0..n)
            .map(|i| match (i + s) % 8 {
                0 => 0.0,
                1 => 1e30,
                2 => -1e30,
                3 => 1e-30,
                4 => -3e-20,
                5 => f32::MAX,
                6 => 1e-3,
                _ => -5.0,
            })
            .collect()
    };
    compare(values(3, n, 1.0), hard, 6, None);
    // Non-finite gradients make non-finite parameters on both.
    let nan = |s: usize| -> Vec<f32> {
        (0..n)
            .map(|i| match (i + s) % 3 {
                0 => f32::NAN,
                1 => f32::INFINITY,
                _ => 0.5,
            })
            .collect()
    };
    compare(values(4, n, 1.0), nan, 2, None);
}

#[test]
fn a_group_of_no_columns_counts_the_step_and_changes_nothing() {
    let (ctx, kernel) = gpu();
    let mut adam = Adam::new();
    let id = adam.add_group("f_rest", 0, 1, schedule(1.0)).unwrap();
    let mut params = vec![1.0f32; 12];
    let grads = vec![1.0f32; 12];
    kernel
        .step_columns(ctx, &mut adam, id, 0, &mut params, &grads, 3, 3..3)
        .unwrap();
    assert_eq!(adam.group(id).step, 1);
    assert!(params.iter().all(|&p| p == 1.0));
}

#[test]
fn a_group_that_does_not_fit_is_an_error_naming_it() {
    let (ctx, kernel) = gpu();
    let mut adam = Adam::new();
    let id = adam.add_group("opacity", 10, 1, schedule(1.0)).unwrap();
    let mut params = vec![0.0f32; 11];
    let err = kernel
        .step(ctx, &mut adam, id, 0, &mut params, &[0.0; 11])
        .unwrap_err();
    assert!(err.to_string().contains("`opacity`"), "{err}");
    assert_eq!(adam.group(id).step, 0, "a refused step is not counted");
}
