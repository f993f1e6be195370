//! MLP: forward against an f64 reference, gradients against f64 finite differences, f16 bounds,
//! hard shapes.

use proptest::prelude::*;
use tiny_nn::{Activation, Mlp, MlpConfig, Precision};

/// Deterministic pseudo-random values in [-s, s] (a tiny LCG; tests only need variety).
fn vals(n: usize, seed: u64, s: f32) -> Vec<f32> {
    let mut x = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * s
        })
        .collect()
}

fn act64(a: Activation, z: f64) -> f64 {
    match a {
        Activation::Identity => z,
        Activation::Relu => z.max(0.0),
        Activation::Sigmoid => 1.0 / (1.0 + (-z).exp()),
    }
}

/// Plain-loop f64 forward of `mlp`'s architecture with parameters `p`.
fn reference(mlp: &Mlp, p: &[f64], x: &[f64], rows: usize) -> Vec<f64> {
    let cfg = mlp.config();
    let ni = cfg.input;
    let last = mlp.layers().len() - 1;
    let mut out = Vec::new();
    for r in 0..rows {
        let xr = &x[r * ni..(r + 1) * ni];
        let mut h: Vec<f64> = xr.to_vec();
        for (l, ly) in mlp.layers().iter().enumerate() {
            let inp: Vec<f64> = if ly.skip_input {
                xr.iter().chain(h.iter()).copied().collect()
            } else {
                h.clone()
            };
            let a = if l == last {
                cfg.output_activation
            } else {
                cfg.hidden_activation
            };
            h = (0..ly.output)
                .map(|o| {
                    let mut z = p[ly.bias_offset + o];
                    for (i, v) in inp.iter().enumerate() {
                        z += v * p[ly.weight_offset + i * ly.output + o];
                    }
                    act64(a, z)
                })
                .collect();
        }
        out.extend(h);
    }
    out
}

fn loss(y: &[f64], c: &[f32]) -> f64 {
    y.iter().zip(c).map(|(a, &b)| a * b as f64).sum()
}

fn small(precision: Precision, out_act: Activation) -> Mlp {
    MlpConfig::new(5, 7, 3, 3)
        .skip_after(1)
        .output_activation(out_act)
        .precision(precision)
        .seed(11)
        .build()
        .unwrap()
}

fn check_grads(mlp: &Mlp, rows: usize) {
    let ni = mlp.input_width();
    let x = vals(rows * ni, 3, 1.5);
    let c = vals(rows * mlp.output_width(), 4, 1.0);
    let (y, cache) = mlp.forward(&x, rows).unwrap();
    let p64: Vec<f64> = mlp
        .params()
        .to_vec_f32()
        .iter()
        .map(|&v| v as f64)
        .collect();
    let x64: Vec<f64> = x.iter().map(|&v| v as f64).collect();
    let y_ref = reference(mlp, &p64, &x64, rows);
    for (a, b) in y.iter().zip(&y_ref) {
        assert!(
            (*a as f64 - b).abs() <= 1e-5 * (1.0 + b.abs()),
            "{a} vs {b}"
        );
    }
    let g = mlp.backward(&cache, &c, true).unwrap();
    let h = 1e-6;
    for i in 0..p64.len() {
        let mut pp = p64.clone();
        pp[i] += h;
        let lp = loss(&reference(mlp, &pp, &x64, rows), &c);
        pp[i] -= 2.0 * h;
        let lm = loss(&reference(mlp, &pp, &x64, rows), &c);
        let fd = (lp - lm) / (2.0 * h);
        let an = g.params[i] as f64;
        assert!(
            (an - fd).abs() <= 1e-4 * (1.0 + fd.abs()),
            "param {i}: {an} vs fd {fd}"
        );
    }
    let gx = g.input.unwrap();
    for i in 0..x64.len() {
        let mut xx = x64.clone();
        xx[i] += h;
        let lp = loss(&reference(mlp, &p64, &xx, rows), &c);
        xx[i] -= 2.0 * h;
        let lm = loss(&reference(mlp, &p64, &xx, rows), &c);
        let fd = (lp - lm) / (2.0 * h);
        let an = gx[i] as f64;
        assert!(
            (an - fd).abs() <= 1e-4 * (1.0 + fd.abs()),
            "input {i}: {an} vs fd {fd}"
        );
    }
}

#[test]
fn gradients_match_f64_finite_differences_with_skip_and_sigmoid() {
    check_grads(&small(Precision::F32, Activation::Sigmoid), 7);
}

#[test]
fn gradients_match_with_identity_output_no_hidden_layers() {
    let mlp = MlpConfig::new(4, 0, 0, 2).seed(5).build().unwrap();
    check_grads(&mlp, 3);
}

#[test]
fn gradients_match_across_row_blocks() {
    // 1100 rows: more than one forward block (256) and backward block (1024), a multiple of
    // neither.
    let mlp = MlpConfig::new(3, 4, 1, 2)
        .hidden_activation(Activation::Sigmoid)
        .seed(2)
        .build()
        .unwrap();
    check_grads(&mlp, 1100);
}

#[test]
fn zero_rows_and_one_row() {
    let mlp = small(Precision::F32, Activation::Identity);
    let (y, cache) = mlp.forward(&[], 0).unwrap();
    assert!(y.is_empty());
    let g = mlp.backward(&cache, &[], true).unwrap();
    assert!(g.params.iter().all(|&v| v == 0.0));
    assert_eq!(g.input.unwrap().len(), 0);
    check_grads(&mlp, 1);
}

#[test]
fn bad_shapes_are_errors() {
    let mlp = small(Precision::F32, Activation::Identity);
    let e = mlp.forward(&[0.0; 9], 2).unwrap_err().to_string();
    assert!(e.contains("MLP input") && e.contains("10"), "{e}");
    let (_, cache) = mlp.forward(&[0.0; 10], 2).unwrap();
    assert!(mlp.backward(&cache, &[0.0; 5], false).is_err());
    assert!(MlpConfig::new(3, 4, 2, 1).skip_after(2).build().is_err());
    assert!(MlpConfig::new(0, 4, 2, 1).build().is_err());
}

#[test]
fn zero_output_starts_at_zero_and_still_learns_the_last_layer() {
    let mlp = MlpConfig::new(3, 8, 2, 4)
        .zero_output(true)
        .build()
        .unwrap();
    let x = vals(30, 1, 1.0);
    let (y, cache) = mlp.forward(&x, 10).unwrap();
    assert!(y.iter().all(|&v| v == 0.0));
    let g = mlp.backward(&cache, &vals(40, 2, 1.0), false).unwrap();
    let last = mlp.layers()[2];
    assert!(g.params[last.weight_offset..].iter().any(|&v| v != 0.0));
}

#[test]
fn init_is_deterministic_from_the_seed() {
    let a = small(Precision::F32, Activation::Identity);
    let b = small(Precision::F32, Activation::Identity);
    assert_eq!(a.params().to_vec_f32(), b.params().to_vec_f32());
    let c = MlpConfig::new(5, 7, 3, 3)
        .skip_after(1)
        .seed(12)
        .build()
        .unwrap();
    assert_ne!(a.params().to_vec_f32(), c.params().to_vec_f32());
}

#[test]
fn f16_agrees_with_f32_within_bounds() {
    let a = small(Precision::F32, Activation::Sigmoid);
    let mut b = small(Precision::F16, Activation::Sigmoid);
    // Same (f16-representable) weights in both, so only activation storage differs.
    let w16 = b.params().to_vec_f32();
    let mut a = a;
    a.set_params(&w16).unwrap();
    b.set_params(&w16).unwrap();
    let rows = 257;
    let x = vals(rows * 5, 9, 1.0);
    let (ya, ca) = a.forward(&x, rows).unwrap();
    let (yb, cb) = b.forward(&x, rows).unwrap();
    let max_err = ya
        .iter()
        .zip(&yb)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f32::max);
    assert!(max_err < 2e-3, "forward max error {max_err}");
    assert_eq!(cb.saturations(), 0);
    let d = vals(rows * 3, 10, 1.0);
    let ga = a.backward(&ca, &d, true).unwrap();
    let gb = b.backward(&cb, &d, true).unwrap();
    let scale = ga.params.iter().map(|v| v.abs()).fold(0.0, f32::max);
    let gerr = ga
        .params
        .iter()
        .zip(&gb.params)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f32::max);
    assert!(
        gerr < 1e-2 * scale,
        "param grad error {gerr} (scale {scale})"
    );
}

#[test]
fn f16_saturates_huge_activations_and_counts_them() {
    let mut mlp = MlpConfig::new(2, 3, 1, 2)
        .precision(Precision::F16)
        .build()
        .unwrap();
    let n = mlp.param_count();
    mlp.set_params(&vec![1000.0; n]).unwrap();
    // Inputs 100 → hidden 2·100·1000 + 1000 = 201000 > 65504: saturates (3 per row), output
    // 3 · 65504 · 1000 saturates too (2 per row); the inputs themselves fit.
    let (y, cache) = mlp.forward(&[100.0; 8], 4).unwrap();
    assert!(y.iter().all(|v| v.is_finite() && *v == 65504.0), "{y:?}");
    assert_eq!(cache.saturations(), 4 * (3 + 2));
    let g = mlp.backward(&cache, &[1.0; 8], true).unwrap();
    assert!(g.params.iter().all(|v| v.is_finite()));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn forward_matches_reference_for_any_rows(rows in 0usize..600, seed in 0u64..1000) {
        let mlp = MlpConfig::new(3, 5, 2, 2).skip_after(0).seed(seed).build().unwrap();
        let x = vals(rows * 3, seed, 2.0);
        let (y, _) = mlp.forward(&x, rows).unwrap();
        let p64: Vec<f64> = mlp.params().to_vec_f32().iter().map(|&v| v as f64).collect();
        let x64: Vec<f64> = x.iter().map(|&v| v as f64).collect();
        let r = reference(&mlp, &p64, &x64, rows);
        prop_assert_eq!(y.len(), r.len());
        for (a, b) in y.iter().zip(&r) {
            prop_assert!((*a as f64 - b).abs() <= 1e-5 * (1.0 + b.abs()));
        }
    }
}

#[test]
fn reused_cache_gives_the_same_results() {
    let a = small(Precision::F16, Activation::Sigmoid);
    let b = small(Precision::F32, Activation::Identity);
    let mut cache = tiny_nn::MlpCache::default();
    // Fill the cache from another network and a larger batch first.
    let x_big = vals(900 * 5, 1, 1.0);
    let _ = b.forward_into(
        900,
        |r0, nr, buf| buf.copy_from_slice(&x_big[r0 * 5..(r0 + nr) * 5]),
        &mut cache,
    );
    let x = vals(300 * 5, 2, 1.0);
    let y = a.forward_into(
        300,
        |r0, nr, buf| buf.copy_from_slice(&x[r0 * 5..(r0 + nr) * 5]),
        &mut cache,
    );
    let (y2, fresh) = a.forward(&x, 300).unwrap();
    assert_eq!(y, y2);
    let d = vals(300 * 3, 3, 1.0);
    assert_eq!(
        a.backward(&cache, &d, true).unwrap(),
        a.backward(&fresh, &d, true).unwrap()
    );
}

/// Spread of the outputs over rows: how much the output depends on the input.
fn output_spread(mlp: &Mlp, rows: usize) -> f64 {
    let x = vals(rows * mlp.config().input, 11, 1.0);
    let (y, _) = mlp.forward(&x, rows).unwrap();
    let d = mlp.config().output;
    (0..d)
        .map(|o| {
            let col: Vec<f64> = (0..rows).map(|r| f64::from(y[r * d + o])).collect();
            let mean = col.iter().sum::<f64>() / rows as f64;
            (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / rows as f64).sqrt()
        })
        .sum::<f64>()
        / d as f64
}

#[test]
fn he_init_keeps_an_eight_layer_network_sensitive_to_its_input() {
    use tiny_nn::Init;
    let build = |init| {
        MlpConfig::new(16, 64, 8, 4)
            .skip_after(4)
            .init(init)
            .seed(3)
            .build()
            .unwrap()
    };
    let (torch, he) = (build(Init::Torch), build(Init::He));
    // PyTorch's default keeps ~1/6 of the second moment per ReLU layer: after 8 layers the
    // output barely moves with the input. He keeps it.
    let (s_torch, s_he) = (output_spread(&torch, 256), output_spread(&he, 256));
    assert!(s_he > 10.0 * s_torch, "spread He {s_he} vs Torch {s_torch}");
    // He: hidden weights within √(6/in), hidden biases zero; the output layer is PyTorch's.
    let p = he.params().to_vec_f32();
    let layers = he.layers();
    for (l, ly) in layers.iter().enumerate() {
        let w = &p[ly.weight_offset..ly.bias_offset];
        let b = &p[ly.bias_offset..ly.bias_offset + ly.output];
        let hidden = l + 1 < layers.len();
        let bound = if hidden {
            (6.0 / ly.input as f32).sqrt()
        } else {
            1.0 / (ly.input as f32).sqrt()
        };
        assert!(w.iter().all(|v| v.abs() <= bound), "layer {l}");
        assert!(w.iter().any(|v| v.abs() > 0.5 * bound), "layer {l}");
        assert_eq!(b.iter().all(|&v| v == 0.0), hidden, "layer {l}");
    }
    // Zero output with He: the network starts at exactly zero.
    let zero = MlpConfig::new(16, 64, 8, 4)
        .init(Init::He)
        .zero_output(true)
        .build()
        .unwrap();
    let (y, _) = zero.forward(&vals(64, 2, 1.0), 4).unwrap();
    assert!(y.iter().all(|&v| v == 0.0));
}
