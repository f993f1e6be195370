//! The GPU MLP (`tiny_nn::gpu::GpuMlp`, both forms of its products: tiled and plain) against
//! the CPU's [`Mlp::forward`] and [`Mlp::backward`] in f32: random shapes (0–4 hidden layers, with and without D-3DGS's skip,
//! identity and sigmoid outputs), row counts on both sides of the weight gradient's chunk
//! (1 024 rows), D-3DGS's own shape (width 256, depth 8, skip after layer 4), and the hard cases
//! (one row, inputs of 1e±6, all-dead ReLUs). Then: a run repeats itself bit for bit; an f16
//! network and inputs of the wrong length are refused.
//!
//! Tolerances: every value within `1e-5 · (|c| + s)` of the CPU's `c`, `s` the root mean square
//! of the compared array. The two sum the same products in different orders (a plain loop over
//! the inputs here, gemm's blocked order there; the weight gradient in chunks of 1 024 rows
//! here, blocks of 1 024 there, summed in another inner order), so each value carries f32
//! rounding of order `√n · 2⁻²⁴` of its terms' magnitude, `n` ≤ 2 600 terms: about 3e-6 of the
//! array's scale at worst, before ReLU's and the chain's amplification across layers. Values
//! near zero by cancellation are held to the array's scale, not their own. Measured on lavapipe:
//! the largest error is half the tolerance (D-3DGS's shape, parameter gradient), about a quarter
//! on the random shapes. A missing adapter
//! fails these tests (CI pins lavapipe); it is not a skip.

use std::sync::OnceLock;

use gpu_core::GpuContext;
use proptest::prelude::*;
use tiny_nn::gpu::{GpuMlp, MlpKernels};
use tiny_nn::{Activation, Mlp, MlpConfig, MlpGrads, Precision};

/// The context and the kernels in both forms (tiled, plain).
fn gpu() -> &'static (GpuContext, [GpuMlp; 2]) {
    static GPU: OnceLock<(GpuContext, [GpuMlp; 2])> = OnceLock::new();
    GPU.get_or_init(|| {
        let ctx = GpuContext::new()
            .unwrap_or_else(|e| panic!("the GPU MLP needs an adapter (CI installs lavapipe): {e}"));
        let kernels = [MlpKernels::Tiled, MlpKernels::Plain].map(|k| {
            let mut mlp = GpuMlp::new(&ctx).unwrap();
            mlp.kernels = k;
            mlp
        });
        (ctx, kernels)
    })
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

fn rms(xs: &[f32]) -> f32 {
    (xs.iter().map(|&x| f64::from(x) * f64::from(x)).sum::<f64>() / xs.len().max(1) as f64).sqrt()
        as f32
}

fn close(what: &str, gpu: &[f32], cpu: &[f32]) {
    assert_eq!(gpu.len(), cpu.len(), "{what}: lengths");
    let s = rms(cpu);
    for (i, (&g, &c)) in gpu.iter().zip(cpu).enumerate() {
        let tol = 1e-5 * (c.abs() + s);
        assert!(
            (g - c).abs() <= tol,
            "{what}[{i}]: gpu {g} vs cpu {c} (tolerance {tol}, rms {s})"
        );
    }
}

/// Forward and backward of `mlp` over `rows` rows on the CPU and on the GPU in both forms of
/// the products, compared.
fn compare(mlp: &Mlp, rows: usize, seed: u64, x_scale: f32, want_input: bool) {
    let (ctx, kernels) = gpu();
    let x = values(seed, rows * mlp.input_width(), x_scale);
    let d_out = values(seed ^ 0xabc, rows * mlp.output_width(), 1.0);
    let (y_cpu, cache) = mlp.forward(&x, rows).unwrap();
    let g_cpu = mlp.backward(&cache, &d_out, want_input).unwrap();
    for kernel in kernels {
        let (y_gpu, g_gpu) = kernel
            .forward_backward(ctx, mlp, &x, rows, &d_out, want_input)
            .unwrap();
        let what = format!("{:?}", kernel.kernels);
        close(&format!("{what} outputs"), &y_gpu, &y_cpu);
        close(
            &format!("{what} parameter gradient"),
            &g_gpu.params,
            &g_cpu.params,
        );
        match (&g_gpu.input, &g_cpu.input) {
            (Some(g), Some(c)) => close(&format!("{what} input gradient"), g, c),
            (None, None) => {}
            (g, c) => panic!(
                "{what} input gradient: gpu {:?} vs cpu {:?}",
                g.is_some(),
                c.is_some()
            ),
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn gpu_mlp_matches_the_cpu(
        input in 1usize..14,
        width in 1usize..40,
        hidden in 0usize..5,
        output in 1usize..11,
        skip_frac in proptest::option::of(0.0f64..1.0),
        sigmoid in any::<bool>(),
        rows in prop_oneof![1usize..60, 1000usize..2600],
        seed in any::<u64>(),
        want_input in any::<bool>(),
    ) {
        let mut config = MlpConfig::new(input, width, hidden, output).seed(seed);
        if let (Some(f), true) = (skip_frac, hidden > 0) {
            config = config.skip_after(((hidden as f64 * f) as usize).min(hidden - 1));
        }
        if sigmoid {
            config = config.output_activation(Activation::Sigmoid);
        }
        compare(&config.build().unwrap(), rows, seed, 1.0, want_input);
    }
}

#[test]
fn gpu_mlp_matches_the_cpu_on_d3dgs_shape() {
    // D-3DGS's deformation network: 63 + 13 sinusoidal inputs, 8 × 256 with the input again
    // after layer 4, 10 outputs.
    let mlp = MlpConfig::new(76, 256, 8, 10)
        .skip_after(4)
        .seed(11)
        .build()
        .unwrap();
    compare(&mlp, 300, 5, 1.0, true);
}

#[test]
fn gpu_mlp_matches_the_cpu_in_hard_cases() {
    let mlp = MlpConfig::new(5, 16, 3, 4)
        .skip_after(1)
        .seed(2)
        .build()
        .unwrap();
    compare(&mlp, 1, 1, 1.0, true);
    compare(&mlp, 37, 2, 1e6, true);
    compare(&mlp, 37, 3, 1e-6, true);
    // Every hidden unit dead: the hidden biases far below zero, the gradient stops at the
    // output layer on both.
    let mut dead = mlp.clone();
    let mut p = vec![0.0f32; dead.param_count()];
    dead.params().read_into(&mut p);
    for layer in &mlp.layers()[..3] {
        p[layer.bias_offset..layer.bias_offset + layer.output].fill(-1e3);
    }
    dead.set_params(&p).unwrap();
    compare(&dead, 50, 4, 1.0, true);
}

#[test]
fn a_gpu_run_repeats_itself_bit_for_bit() {
    let (ctx, [kernel, _]) = gpu();
    let mlp = MlpConfig::new(7, 24, 3, 3)
        .skip_after(1)
        .seed(9)
        .build()
        .unwrap();
    let rows = 2_100;
    let x = values(1, rows * 7, 1.0);
    let d_out = values(2, rows * 3, 1.0);
    let run = || -> (Vec<f32>, MlpGrads) {
        kernel
            .forward_backward(ctx, &mlp, &x, rows, &d_out, true)
            .unwrap()
    };
    let (a, b) = (run(), run());
    assert!(
        a.0.iter()
            .zip(&b.0)
            .all(|(p, q)| p.to_bits() == q.to_bits())
    );
    assert_eq!(
        a.1.params.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        b.1.params.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}

#[test]
fn an_f16_network_and_wrong_lengths_are_refused() {
    let (ctx, [kernel, _]) = gpu();
    let f16 = MlpConfig::new(3, 8, 1, 2)
        .precision(Precision::F16)
        .build()
        .unwrap();
    let err = kernel
        .forward_backward(ctx, &f16, &[0.0; 6], 2, &[0.0; 4], false)
        .unwrap_err();
    assert!(err.to_string().contains("f16"), "{err}");
    let f32 = MlpConfig::new(3, 8, 1, 2).build().unwrap();
    let err = kernel
        .forward_backward(ctx, &f32, &[0.0; 5], 2, &[0.0; 4], false)
        .unwrap_err();
    assert!(err.to_string().contains("5 inputs"), "{err}");
}
