//! Hand-computed sequences, snapshot-tested: constant velocity, non-uniform times, the warm-up
//! stages, frames visited in random order, gaps larger than max_gap.

mod common;

use common::*;
use evo_state::{EvoConfig, Frames, Gain, Gains};

fn assert_close(a: &[f32], b: &[f32], tol: f32) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= tol, "element {i}: {x} vs {y}");
    }
}

/// z_i(t) = x0_i + v_i t: after warm-up the prior equals the observation exactly.
fn constant_velocity(times: Vec<f32>) -> String {
    let frames = Frames::new(times).unwrap();
    let config = EvoConfig {
        layout: position_only(),
        gain: Gain::Fixed(0.3),
        ..EvoConfig::default()
    };
    let mut st = state(config, frames.clone(), 2);
    let x0 = [0.5f32, -1.0, 2.0, 0.0, 0.25, 1.0];
    let v = [1.0f32, 2.0, -0.5, -3.0, 0.0, 4.0];
    let mut out = String::new();
    for k in 0..frames.len() {
        let t = frames.times()[k];
        let z: Vec<f32> = x0.iter().zip(&v).map(|(x, v)| x + v * t).collect();
        let step = train(&mut st, k, &z);
        if let Some(prior) = step.prior() {
            assert_close(prior, &z, 1e-5);
        }
        assert_close(step.corrected(), &z, 1e-5);
        out += &trace(&st, &step, &z);
    }
    out
}

#[test]
fn constant_velocity_prior_is_exact() {
    insta::assert_snapshot!(constant_velocity((0..6).map(|k| k as f32 * 0.2).collect()));
}

#[test]
fn non_uniform_times_prior_is_exact() {
    insta::assert_snapshot!(constant_velocity(vec![0.0, 0.1, 0.3, 0.35, 0.6, 1.0]));
}

/// z = [k², 0, 0] at uniform frames, gain fixed at 0.25 (h = 3). Every value below is computed
/// by hand in the comments.
#[test]
fn warm_up_stages_by_hand() {
    let config = EvoConfig {
        layout: position_only(),
        gain: Gain::Fixed(0.25),
        ..EvoConfig::default()
    };
    let mut st = state(config, uniform_frames(5), 1);
    let z = |k: usize| vec![(k * k) as f32, 0.0, 0.0];
    let mut out = String::new();
    let expect = [
        // h = 0: d~ = z = 0.
        (0usize, None, Gains::Observation, 0.0f32, None),
        // h = 1: d~ = z = 1.
        (1, None, Gains::Observation, 1.0, None),
        // h = 2: prior = 2·1 - 0 = 2, K = 0.5, d~ = 0.5·2 + 0.5·4 = 3, m = 0.1·(4 - 2) = 0.2.
        (2, Some(2.0f32), Gains::Uniform(0.5), 3.0, Some(0.2f32)),
        // h = 3: prior = 3 + (3 - 1) = 5, K = 0.25, d~ = 0.75·5 + 0.25·9 = 6,
        // m = 0.9·0.2 + 0.1·(9 - 5) = 0.58.
        (3, Some(5.0), Gains::Uniform(0.25), 6.0, Some(0.58)),
        // prior = 6 + (6 - 3) = 9, d~ = 0.75·9 + 0.25·16 = 10.75, m = 0.9·0.58 + 0.1·7 = 1.222.
        (4, Some(9.0), Gains::Uniform(0.25), 10.75, Some(1.222)),
    ];
    for (k, prior, gains, corrected, memory) in expect {
        let step = train(&mut st, k, &z(k));
        assert_eq!(step.history().len, k.min(3));
        assert_eq!(step.prior().map(|p| p[0]), prior);
        assert_eq!(step.gains(), &gains);
        assert!((step.corrected()[0] - corrected).abs() < 1e-6, "frame {k}");
        if let Some(m) = memory {
            assert!(
                (step.memory_next().unwrap()[0] - m).abs() < 1e-6,
                "frame {k}"
            );
            assert!((st.memory()[0] - m).abs() < 1e-6);
        } else {
            assert!(st.memory().iter().all(|&m| m == 0.0));
        }
        out += &trace(&st, &step, &z(k));
    }
    // Statistics at frame 3: v1 = 3 - 1 = 2, v2 = 1 - 0 = 1, same direction; SPEC's ε gives
    // θ = arccos(2 / (2 + 1e-6)) ≈ 1e-3, not exactly 0.
    let step = st.forward(st.frames().times()[3], &z(3)).unwrap();
    let s = step.stats().unwrap()[0];
    assert_eq!((s.speed_last, s.speed_prev), (2.0, 1.0));
    assert!(
        (s.theta as f64 - (2.0f64 / (2.0 + 1e-6)).acos()).abs() < 1e-6,
        "{}",
        s.theta
    );
    insta::assert_snapshot!(out);
}

/// The learned stage: K comes from Ψ, one value in (0, 1) per Gaussian, shared by components.
#[test]
fn learned_gain_stage() {
    let mut st = state(EvoConfig::default(), uniform_frames(5), 3);
    let d = st.dim();
    let mut out = String::new();
    for k in 0..5 {
        let z: Vec<f32> = (0..3 * d)
            .map(|e| ((e * 7 + k * 3) % 11) as f32 * 0.1 + k as f32 * 0.2)
            .collect();
        let step = train(&mut st, k, &z);
        if k >= 3 {
            let Gains::Learned(gains) = step.gains() else {
                panic!("frame {k}: gain not learned")
            };
            let prior = step.prior().unwrap();
            for (i, &g) in gains.iter().enumerate() {
                assert!(g > 0.0 && g < 1.0);
                for j in 0..d {
                    let e = i * d + j;
                    let expected = (1.0 - g) * prior[e] + g * z[e];
                    assert!((step.corrected()[e] - expected).abs() < 1e-5);
                }
            }
        }
        out += &trace(&st, &step, &z);
    }
    insta::assert_snapshot!(out);
}

/// Frames visited in random order: the history only uses committed frames.
#[test]
fn frames_in_random_order() {
    let config = EvoConfig {
        layout: position_only(),
        gain: Gain::Fixed(0.5),
        ..EvoConfig::default()
    };
    let mut st = state(config, uniform_frames(6), 1);
    let mut out = String::new();
    let expected_history: [(usize, &[usize]); 6] = [
        (3, &[]),
        (0, &[]),
        (1, &[0]),
        (4, &[3, 1, 0]),
        (2, &[1, 0]),
        (5, &[4, 3, 2]),
    ];
    for (k, history) in expected_history {
        let z = vec![(k * k) as f32, k as f32, 1.0];
        let step = train(&mut st, k, &z);
        assert_eq!(step.history().frames(), history, "frame {k}");
        if k == 4 {
            // s = (t4 - t3)/(t3 - t1) = 1/2: prior = 9 + 0.5·(9 - 1) = 13.
            assert!((step.prior().unwrap()[0] - 13.0).abs() < 1e-5);
        }
        out += &trace(&st, &step, &z);
    }
    insta::assert_snapshot!(out);
}

/// Gaps larger than max_gap cut the history.
#[test]
fn gaps_larger_than_max_gap() {
    let config = EvoConfig {
        layout: position_only(),
        max_gap: 2,
        ..EvoConfig::default()
    };
    let mut st = state(config, uniform_frames(9), 1);
    for k in [0, 1, 2, 6] {
        train(&mut st, k, &[k as f32, 0.0, 0.0]);
    }
    let mut out = String::new();
    // Query positions: frame 4 (2 after frame 2: ok), 5 (3 after: cut), 8 (6 then 2: gap 4).
    for (k, history) in [
        (4usize, &[2usize, 1, 0][..]),
        (5, &[]),
        (8, &[6]),
        (7, &[6]),
    ] {
        let t = st.frames().times()[k];
        let z = [k as f32, 0.0, 0.0];
        let step = st.forward(t, &z).unwrap();
        assert_eq!(step.history().frames(), history, "query at frame {k}");
        out += &trace(&st, &step, &z);
    }
    insta::assert_snapshot!(out);
}

/// Evaluation between and beyond training frames: read-only, time-scaled prior.
#[test]
fn queries_between_and_beyond_frames() {
    let config = EvoConfig {
        layout: position_only(),
        gain: Gain::Fixed(0.0),
        ..EvoConfig::default()
    };
    let mut st = state(config, uniform_frames(5), 1);
    for k in 0..5 {
        train(&mut st, k, &[k as f32, 0.0, 0.0]);
    }
    let before = st.clone();
    let mut out = String::new();
    // Prior only (K = 0): linear extrapolation from the buffer: x = 4·t.
    for t in [0.6f32, 1.0, 1.2, 2.0] {
        let step = st.forward(t, &[100.0, 0.0, 0.0]).unwrap();
        assert!((step.corrected()[0] - 4.0 * t).abs() < 1e-4, "t = {t}");
        out += &trace(&st, &step, &[100.0, 0.0, 0.0]);
    }
    // Queries off the frame times cannot commit, and a failed commit writes nothing.
    let mut fresh = before.clone();
    for t in [0.6f32, 1.2, 2.0] {
        let step = fresh.forward(t, &[100.0, 0.0, 0.0]).unwrap();
        assert!(matches!(
            fresh.commit(&step),
            Err(evo_state::EvoError::NotAFrame(_))
        ));
    }
    assert_eq!(fresh, before);
    insta::assert_snapshot!(out);
}
