//! Finite-difference checks of the backward pass: the z path (for every warm-up stage and gain
//! mode) and the Ψ path. The loss is `Σ g·d̃ + λ1 L_sup + λ2 L_prior` with a fixed random g
//! standing in for the render gradient, evaluated in f64 from the forward pass's outputs.

mod common;

use common::*;
use evo_state::{EvoConfig, EvoState, Gain, Step};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const N: usize = 6;

fn random(rng: &mut ChaCha8Rng, len: usize, scale: f32) -> Vec<f32> {
    (0..len).map(|_| rng.random_range(-scale..scale)).collect()
}

/// The total loss, recomputed independently of `backward` (f64).
fn loss(st: &EvoState, step: &Step, z: &[f32], g: &[f32], opacity: &[f32]) -> f64 {
    let d = st.dim();
    let c = st.config();
    let n = step.rows() as f64;
    let mut total = 0.0;
    for e in 0..z.len() {
        let (zv, dv) = (z[e] as f64, step.corrected()[e] as f64);
        total += g[e] as f64 * dv + c.lambda_sup as f64 * (dv - zv).powi(2) / n;
        if let Some(p) = step.prior() {
            total += c.lambda_prior as f64 * opacity[e / d] as f64 * (p[e] as f64 - zv).powi(2) / n;
        }
    }
    total
}

/// A state with `committed` frames trained on random observations.
fn setup(config: EvoConfig, committed: usize, seed: u64) -> (EvoState, ChaCha8Rng) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut st = state(config, uniform_frames(6), N);
    let d = st.dim();
    // Ψ more decisive than at initialisation, so K varies between Gaussians.
    let scaled: Vec<f32> = st.psi().params().iter().map(|p| p * 3.0).collect();
    st.psi_mut().set_params(&scaled).unwrap();
    for k in 0..committed {
        let z: Vec<f32> = random(&mut rng, N * d, 1.0)
            .iter()
            .map(|v| v + k as f32 * 0.3)
            .collect();
        train(&mut st, k, &z);
    }
    (st, rng)
}

/// Zeroes Ψ's first-layer weights on the memory inputs: then K does not depend on z (m is a
/// constant for autodiff, but a finite difference in z would move it).
fn cut_memory_inputs(st: &mut EvoState) {
    let d = st.dim();
    // tiny-nn's layout: W of layer 0 is row-major inputs × outputs, inputs [m (D), |v2|, |v1|, θ].
    let layer = st.psi().mlp().layers()[0];
    let mut params = st.psi().params();
    for c in 0..d {
        for j in 0..layer.output {
            params[layer.weight_offset + c * layer.output + j] = 0.0;
        }
    }
    st.psi_mut().set_params(&params).unwrap();
}

fn check_z_path(config: EvoConfig, committed: usize, expect_h: usize) {
    let (mut st, mut rng) = setup(config, committed, 11 + committed as u64);
    cut_memory_inputs(&mut st);
    let d = st.dim();
    let t = st.frames().times()[committed];
    let z = random(&mut rng, N * d, 2.0);
    let g = random(&mut rng, N * d, 1.0);
    let opacity: Vec<f32> = (0..N).map(|_| rng.random_range(0.0..1.0)).collect();
    let step = st.forward(t, &z).unwrap();
    assert_eq!(step.history().len, expect_h);
    let back = st.backward(&step, &z, &g, &opacity).unwrap();
    // Loss values reported by backward agree with the independent computation.
    let c = st.config();
    let reported = g
        .iter()
        .zip(step.corrected())
        .map(|(a, b)| *a as f64 * *b as f64)
        .sum::<f64>()
        + c.lambda_sup as f64 * back.losses.sup
        + c.lambda_prior as f64 * back.losses.prior;
    let direct = loss(&st, &step, &z, &g, &opacity);
    assert!(
        (reported - direct).abs() < 1e-9 * (1.0 + direct.abs()),
        "{reported} vs {direct}"
    );
    let h = 1e-2f32;
    for e in 0..z.len() {
        let mut zp = z.clone();
        zp[e] += h;
        let mut zm = z.clone();
        zm[e] -= h;
        let lp = loss(&st, &st.forward(t, &zp).unwrap(), &zp, &g, &opacity);
        let lm = loss(&st, &st.forward(t, &zm).unwrap(), &zm, &g, &opacity);
        let fd = (lp - lm) / (2.0 * h as f64);
        let an = back.dz[e] as f64;
        assert!(
            (fd - an).abs() <= 2e-4 + 1e-3 * fd.abs(),
            "h={expect_h} element {e}: fd {fd} vs analytic {an}"
        );
    }
}

#[test]
fn z_path_before_warm_up() {
    check_z_path(EvoConfig::default(), 1, 1);
}

#[test]
fn z_path_second_order_warm_up() {
    check_z_path(EvoConfig::default(), 2, 2);
}

#[test]
fn z_path_learned_gain() {
    check_z_path(EvoConfig::default(), 3, 3);
}

#[test]
fn z_path_fixed_gains() {
    for k in [0.0, 0.5, 1.0] {
        check_z_path(
            EvoConfig {
                gain: Gain::Fixed(k),
                ..EvoConfig::default()
            },
            4,
            3,
        );
    }
}

#[test]
fn z_path_with_opacity_and_colour_components() {
    let mut config = EvoConfig::default();
    config.layout.opacity = true;
    config.layout.colour = true;
    config.lambda_sup = 0.7;
    config.lambda_prior = 1.3;
    check_z_path(config, 3, 3);
}

/// Ψ path: directional finite differences along random parameter directions (robust to ReLU
/// kinks), and per-parameter checks of the smooth output layer.
#[test]
fn psi_path() {
    let (st, mut rng) = setup(EvoConfig::default(), 3, 5);
    let d = st.dim();
    let t = st.frames().times()[3];
    let z = random(&mut rng, N * d, 2.0);
    let g = random(&mut rng, N * d, 1.0);
    let opacity = vec![0.5f32; N];
    let step = st.forward(t, &z).unwrap();
    let back = st.backward(&step, &z, &g, &opacity).unwrap();
    let dpsi = back.dpsi.expect("learned gain gives Ψ gradients");
    let loss_at = |params: &[f32]| {
        let mut s = st.clone();
        s.psi_mut().set_params(params).unwrap();
        loss(&s, &s.forward(t, &z).unwrap(), &z, &g, &opacity)
    };
    let base = st.psi().params();
    // Central differences along a direction; ReLU kinks of the scaled-up Ψ can sit within a
    // step, so the check passes when some step in a short decreasing list agrees (a wrong
    // gradient disagrees at every step).
    let fd_along = |u: &[f32]| -> Vec<f64> {
        [1e-3f32, 3e-4, 1e-4]
            .iter()
            .map(|&h| {
                let plus: Vec<f32> = base.iter().zip(u).map(|(p, u)| p + h * u).collect();
                let minus: Vec<f32> = base.iter().zip(u).map(|(p, u)| p - h * u).collect();
                (loss_at(&plus) - loss_at(&minus)) / (2.0 * h as f64)
            })
            .collect()
    };
    let agrees = |fds: &[f64], an: f64| {
        fds.iter()
            .any(|fd| (fd - an).abs() <= 3e-3 + 5e-3 * fd.abs())
    };
    for trial in 0..8 {
        let u = random(&mut rng, base.len(), 1.0);
        let an: f64 = dpsi
            .iter()
            .zip(&u)
            .map(|(g, u)| *g as f64 * *u as f64)
            .sum();
        let fds = fd_along(&u);
        assert!(agrees(&fds, an), "direction {trial}: fd {fds:?} vs {an}");
        assert!(
            an.abs() > 1e-3,
            "direction {trial}: gradient too small to test: {an}"
        );
    }
    // Output layer, one parameter at a time: the last HIDDEN + 1 parameters.
    for i in base.len() - evo_state::gain::HIDDEN - 1..base.len() {
        let mut u = vec![0.0f32; base.len()];
        u[i] = 1.0;
        let fds = fd_along(&u);
        assert!(
            agrees(&fds, dpsi[i] as f64),
            "param {i}: fd {fds:?} vs {}",
            dpsi[i]
        );
    }
}

/// Fixed gains and warm-up have no Ψ gradient; evolution off passes the render gradient through.
#[test]
fn no_psi_gradient_without_learned_gain() {
    let (st, mut rng) = setup(
        EvoConfig {
            gain: Gain::Fixed(0.5),
            ..EvoConfig::default()
        },
        3,
        9,
    );
    let d = st.dim();
    let z = random(&mut rng, N * d, 1.0);
    let step = st.forward(st.frames().times()[3], &z).unwrap();
    let back = st
        .backward(&step, &z, &vec![0.0; N * d], &[1.0; N])
        .unwrap();
    assert!(back.dpsi.is_none());
    let (off, mut rng) = setup(
        EvoConfig {
            evolution: false,
            ..EvoConfig::default()
        },
        4,
        3,
    );
    let z = random(&mut rng, N * d, 1.0);
    let g = random(&mut rng, N * d, 1.0);
    let step = off.forward(off.frames().times()[4], &z).unwrap();
    assert_eq!(step.corrected(), &z[..]);
    let back = off.backward(&step, &z, &g, &[1.0; N]).unwrap();
    assert_eq!(back.dz, g);
    assert_eq!(back.losses, evo_state::Losses::default());
}
