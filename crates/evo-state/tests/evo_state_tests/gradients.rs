//! Finite-difference checks of the backward pass: the z path (for every warm-up stage and gain
//! mode), the Ψ path (with Ψ's inputs normalised by the batch's RMS and by the running RMS), and
//! the re-queried history path (d̂ a function of the observations at the history times). The
//! loss is `Σ g·d̃ + λ1 L_sup + λ2 L_prior` with a fixed random g standing in for the render
//! gradient, evaluated in f64 from the forward pass's outputs.

use crate::common;

use common::*;
use evo_state::{EvoConfig, EvoState, Gain, HistoryMode, Step};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const N: usize = 6;

fn random(rng: &mut ChaCha8Rng, len: usize, scale: f32) -> Vec<f32> {
    (0..len).map(|_| rng.random_range(-scale..scale)).collect()
}

/// The total loss, recomputed independently of `backward` (f64).
fn loss(st: &EvoState, step: &Step, z: &[f32], g: &[f32], opacity: &[f32]) -> f64 {
    loss_with_prior(st, step, z, g, opacity, step.prior())
}

/// The total loss with `sg_prior` as the d̂ inside L_prior (the stop-gradient: a finite
/// difference must hold it at the unperturbed value).
fn loss_with_prior(
    st: &EvoState,
    step: &Step,
    z: &[f32],
    g: &[f32],
    opacity: &[f32],
    sg_prior: Option<&[f32]>,
) -> f64 {
    let d = st.dim();
    let c = st.config();
    let n = step.rows() as f64;
    let mut total = 0.0;
    for e in 0..z.len() {
        let (zv, dv) = (z[e] as f64, step.corrected()[e] as f64);
        total += g[e] as f64 * dv + c.lambda_sup as f64 * (dv - zv).powi(2) / n;
        if let Some(p) = sg_prior {
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

/// Ψ path at the first learned step (Ψ's inputs normalised by the batch's own RMS) and after
/// two learned steps (by the running RMS).
#[test]
fn psi_path() {
    psi_path_after(3);
    psi_path_after(5);
}

/// Ψ path: directional finite differences along random parameter directions (robust to ReLU
/// kinks), and per-parameter checks of the smooth output layer.
fn psi_path_after(committed: usize) {
    let (st, mut rng) = setup(EvoConfig::default(), committed, 5);
    assert_eq!(st.input_norm().rms().is_some(), committed > 3);
    let d = st.dim();
    let t = st.frames().times()[committed];
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

/// Observations at the history times for the "without buffer" ablation: one random block per
/// frame time, served by an [`evo_state::ObservationSource`].
fn requery_source(
    blocks: &[Vec<f32>],
    times: &[f32],
) -> impl FnMut(f32, &mut [f32]) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    move |t: f32, out: &mut [f32]| {
        let k = times.iter().position(|&x| x == t).expect("a frame time");
        out.copy_from_slice(&blocks[k]);
        Ok(())
    }
}

/// History re-queried from Φ: d̂ = z_k1 + s (z_k1 - z_k2) is a function of the observations at
/// the history times, and the rendering loss and L_sup reach them through it (L_prior does not:
/// its d̂ is held by the stop-gradient). Central differences of the loss in each history block's
/// elements match [`evo_state::Backward::history`]; k3's block (statistics only) has no
/// gradient, and the gradient in the current z is unchanged by the re-query.
fn check_requery_path(gain: Gain, query: usize, expect_h: usize) {
    let config = EvoConfig {
        history: HistoryMode::Requery,
        gain,
        ..EvoConfig::default()
    };
    let st = state(config, uniform_frames(6), N);
    let d = st.dim();
    let mut rng = ChaCha8Rng::seed_from_u64(21 + query as u64);
    let times = st.frames().times().to_vec();
    let blocks: Vec<Vec<f32>> = (0..times.len())
        .map(|k| {
            random(&mut rng, N * d, 1.0)
                .iter()
                .map(|v| v + 0.4 * k as f32)
                .collect()
        })
        .collect();
    let t = times[query];
    let z = random(&mut rng, N * d, 2.0);
    let g = random(&mut rng, N * d, 1.0);
    let opacity: Vec<f32> = (0..N).map(|_| rng.random_range(0.0..1.0)).collect();
    let step = st
        .forward_with(t, &z, &mut requery_source(&blocks, &times))
        .unwrap();
    assert_eq!(step.history().len, expect_h);
    let back = st.backward(&step, &z, &g, &opacity).unwrap();
    let sg_prior = step.prior().unwrap().to_vec();
    let history = step.history();
    assert_eq!(back.history.len(), 2);
    let h = 1e-2f32;
    let loss_at = |blocks: &[Vec<f32>], z: &[f32]| {
        let step = st
            .forward_with(t, z, &mut requery_source(blocks, &times))
            .unwrap();
        loss_with_prior(&st, &step, z, &g, &opacity, Some(&sg_prior))
    };
    let mut largest = 0.0f64;
    for (j, &k) in history.frames().iter().enumerate() {
        let analytic = back.history.get(j).map(|hg| {
            assert_eq!(hg.time, times[k]);
            &hg.dz
        });
        for e in 0..N * d {
            let mut plus = blocks.clone();
            plus[k][e] += h;
            let mut minus = blocks.clone();
            minus[k][e] -= h;
            let fd = (loss_at(&plus, &z) - loss_at(&minus, &z)) / (2.0 * h as f64);
            let an = analytic.map_or(0.0, |a| a[e] as f64);
            largest = largest.max(an.abs());
            assert!(
                (fd - an).abs() <= 2e-4 + 1e-3 * fd.abs(),
                "history frame {k} element {e}: fd {fd} vs analytic {an}"
            );
        }
    }
    if gain == Gain::Fixed(1.0) {
        // Observation only: d̃ = z does not depend on d̂.
        assert_eq!(largest, 0.0);
    } else {
        assert!(
            largest > 1e-2,
            "history gradients too small to test: {largest}"
        );
    }
    for e in 0..N * d {
        let mut zp = z.clone();
        zp[e] += h;
        let mut zm = z.clone();
        zm[e] -= h;
        let fd = (loss_at(&blocks, &zp) - loss_at(&blocks, &zm)) / (2.0 * h as f64);
        let an = back.dz[e] as f64;
        assert!(
            (fd - an).abs() <= 2e-4 + 1e-3 * fd.abs(),
            "z element {e}: fd {fd} vs analytic {an}"
        );
    }
}

#[test]
fn requeried_history_path_warm_up() {
    check_requery_path(Gain::Learned, 2, 2);
}

#[test]
fn requeried_history_path_fixed_gains() {
    for k in [0.0, 0.3, 1.0] {
        check_requery_path(Gain::Fixed(k), 3, 3);
    }
}

/// Non-uniform spacing: s = (t - t_k1)/(t_k1 - t_k2) != 1 scales the two history gradients.
#[test]
fn requeried_history_gradients_scale_with_the_spacing() {
    let config = EvoConfig {
        history: HistoryMode::Requery,
        gain: Gain::Fixed(0.0),
        lambda_sup: 0.0,
        ..EvoConfig::default()
    };
    let frames = evo_state::Frames::new(vec![0.0, 0.1, 0.4]).unwrap();
    let st = EvoState::new(config, frames, 1, 7).unwrap();
    let d = st.dim();
    let blocks = vec![vec![0.0f32; d], vec![1.0; d], vec![0.0; d]];
    let times = st.frames().times().to_vec();
    let z = vec![0.5f32; d];
    let step = st
        .forward_with(0.4, &z, &mut requery_source(&blocks, &times))
        .unwrap();
    // s = (0.4 - 0.1)/(0.1 - 0) = 3, K = 0.5 (warm-up): with g = 1 per element and λ1 = 0,
    // dL/dd̂ = (1 - K)·1 = 0.5, dL/dz_k1 = (1 + s)·0.5 = 2, dL/dz_k2 = -s·0.5 = -1.5.
    let back = st.backward(&step, &z, &vec![1.0; d], &[1.0]).unwrap();
    assert_eq!(back.history[0].time, 0.1);
    assert!(back.history[0].dz.iter().all(|&v| (v - 2.0).abs() < 1e-5));
    assert_eq!(back.history[1].time, 0.0);
    assert!(back.history[1].dz.iter().all(|&v| (v + 1.5).abs() < 1e-5));
    // With the buffer the prior is a constant: no history gradients.
    let mut buffered = state(EvoConfig::default(), uniform_frames(4), 1);
    train(&mut buffered, 0, &vec![0.0; d]);
    train(&mut buffered, 1, &vec![1.0; d]);
    let step = buffered
        .forward(buffered.frames().times()[2], &vec![0.0; d])
        .unwrap();
    assert_eq!(step.history().len, 2);
    let back = buffered
        .backward(&step, &vec![0.0; d], &vec![1.0; d], &[1.0])
        .unwrap();
    assert!(back.history.is_empty());
}
