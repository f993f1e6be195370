//! Hand-computed sequences, snapshot-tested: constant velocity, non-uniform times, the warm-up
//! stages, frames visited in random order, gaps larger than max_gap.

use crate::common;

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
        // The commit wrote m to M[k] (zero before a prior exists).
        let committed = st.memory().unwrap().row(k, 0)[0];
        if let Some(m) = memory {
            assert!(
                (step.memory_next().unwrap()[0] - m).abs() < 1e-6,
                "frame {k}"
            );
            assert!((committed - m).abs() < 1e-6);
        } else {
            assert_eq!(committed, 0.0);
        }
        out += &trace(&st, &step, &z(k));
    }
    // Statistics at frame 3: v1 = 3 - 1 = 2, v2 = 1 - 0 = 1, same direction; DESIGN §4.7's ε gives
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

/// Frames visited in random order: the history only uses committed frames, and the residual
/// memory read is M[k1], the one committed with the history's latest frame, not whichever frame
/// trained last.
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
        let m = step.memory_next().map(|m| m[0]);
        match k {
            // s = (t4 - t3)/(t3 - t1) = 1/2: prior = 9 + 0.5·(9 - 1) = 13; M[3] = 0 (frame 3
            // trained first, h = 0), so m = 0.1·(16 - 13) = 0.3.
            4 => {
                assert!((step.prior().unwrap()[0] - 13.0).abs() < 1e-5);
                assert!((m.unwrap() - 0.3).abs() < 1e-6);
            }
            // History [1, 0]: prior = 2·1 - 0 = 2, M[1] = 0 (frame 1 had h = 1):
            // m = 0.1·(4 - 2) = 0.2, although frame 4 (m = 0.3) trained just before.
            2 => assert!((m.unwrap() - 0.2).abs() < 1e-6),
            // History [4, 3, 2]: the prior comes from the buffer's corrected states d̃_4 = 14.5
            // and d̃_3 = 9: 14.5 + (14.5 - 9) = 20; M[4] = 0.3: m = 0.9·0.3 + 0.1·(25 - 20) = 0.77.
            5 => {
                assert!((step.prior().unwrap()[0] - 20.0).abs() < 1e-5);
                assert!((m.unwrap() - 0.77).abs() < 1e-6);
            }
            _ => assert_eq!(m, None),
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

/// Ψ's inputs divided by their running RMS (DESIGN §4.9), by hand. K is fixed (0.25) so every value
/// is computable; the inputs and the running RMS do not depend on the gain mode. Two Gaussians,
/// position only: row 0 follows z = [k², 0, 0] (as `warm_up_stages_by_hand`), row 1 moves at a
/// constant velocity z = [0, 2k, 0] (prior exact, m = 0).
#[test]
fn psi_inputs_divided_by_their_running_rms() {
    let config = EvoConfig {
        layout: position_only(),
        gain: Gain::Fixed(0.25),
        ..EvoConfig::default()
    };
    // Times exact in binary, so s = 1 exactly and row 1's prior is exact (m = 0, not rounding).
    let frames = Frames::new(vec![0.0, 0.25, 0.5, 0.75, 1.0, 1.25]).unwrap();
    let mut st = state(config, frames, 2);
    let z = |k: usize| vec![(k * k) as f32, 0.0, 0.0, 0.0, 2.0 * k as f32, 0.0];
    for k in 0..3 {
        let step = train(&mut st, k, &z(k));
        assert_eq!(step.psi_inputs(), None);
        assert_eq!(st.input_norm().rms(), None);
    }
    let theta = |v1: f64, v2: f64| (v1 * v2 / (v1 * v2 + 1e-6)).acos();
    // Frame 3, the first with statistics. Raw inputs [m (3), |v2|, |v1|, θ]:
    //   row 0: m = 0.9·0.2 + 0.1·(9 - 5) = 0.58, v2 = 1 - 0 = 1, v1 = 3 - 1 = 2;
    //   row 1: m = 0, |v2| = |v1| = 2.
    // No running statistics yet: the batch's own mean squares normalise,
    //   ms = [0.58²/2, 0, 0, (1 + 4)/2, (4 + 4)/2] = [0.1682, 0, 0, 2.5, 4].
    let step = train(&mut st, 3, &z(3));
    let ms3 = [0.58f64 * 0.58 / 2.0, 0.0, 0.0, 2.5, 4.0];
    let expected3 = [
        [
            0.58 / ms3[0].sqrt(),
            0.0,
            0.0,
            1.0 / 2.5f64.sqrt(),
            2.0 / 2.0,
            theta(2.0, 1.0),
        ],
        [
            0.0,
            0.0,
            0.0,
            2.0 / 2.5f64.sqrt(),
            2.0 / 2.0,
            theta(2.0, 2.0),
        ],
    ];
    assert_inputs(step.psi_inputs().unwrap(), &expected3);
    // m of row 0 normalised by its own batch RMS: 0.58 / (0.58/√2) = √2.
    assert!((step.psi_inputs().unwrap()[0] - 2f32.sqrt()).abs() < 1e-5);
    // The commit folded ms into the running average: ema = 0.01·ms, weight = 0.01, RMS = √ms.
    let rms = st.input_norm().rms().unwrap();
    for (r, m) in rms.iter().zip(ms3) {
        assert!((r - m.sqrt()).abs() < 1e-6, "{rms:?}");
    }
    let mut out = inputs_trace(&step);
    // Frame 4: row 0 m = 0.9·0.58 + 0.1·(16 - 9) = 1.222, v2 = 2, v1 = 3; row 1 as before.
    // Normalised by the running RMS of frame 3 (not by frame 4's own batch). The memory's y and
    // z components have RMS 0: they are divided by the floor (the motion floor, 1e-6) and stay 0.
    let step = train(&mut st, 4, &z(4));
    let expected4 = [
        [
            1.222 / ms3[0].sqrt(),
            0.0,
            0.0,
            2.0 / 2.5f64.sqrt(),
            3.0 / 2.0,
            theta(3.0, 2.0),
        ],
        [
            0.0,
            0.0,
            0.0,
            2.0 / 2.5f64.sqrt(),
            2.0 / 2.0,
            theta(2.0, 2.0),
        ],
    ];
    assert_inputs(step.psi_inputs().unwrap(), &expected4);
    out += &inputs_trace(&step);
    // After frame 4: ema = 0.99·0.01·ms3 + 0.01·ms4, weight = 1 - 0.99², ms4 = [1.222²/2, 0, 0,
    // (4 + 4)/2, (9 + 4)/2].
    let ms4 = [1.222f64 * 1.222 / 2.0, 0.0, 0.0, 4.0, 6.5];
    let weight = 1.0 - 0.99f64 * 0.99;
    let rms = st.input_norm().rms().unwrap();
    for j in 0..5 {
        let expected = ((0.99 * 0.01 * ms3[j] + 0.01 * ms4[j]) / weight).sqrt();
        assert!((rms[j] - expected).abs() < 1e-6, "feature {j}: {rms:?}");
    }
    // Evaluation reads the running RMS frozen: a query writes nothing.
    let before = st.clone();
    let step = st.forward(1.4, &z(5)).unwrap();
    assert!(step.psi_inputs().is_some());
    assert_eq!(st, before);
    out += &format!("running rms after frame 4: {}\n", fmt_list(&rms));
    insta::assert_snapshot!(out);
}

fn assert_inputs(got: &[f32], expected: &[[f64; 6]; 2]) {
    for (r, row) in expected.iter().enumerate() {
        for (j, e) in row.iter().enumerate() {
            let g = got[r * 6 + j] as f64;
            assert!(
                (g - e).abs() < 1e-5 * (1.0 + e.abs()),
                "row {r} input {j}: {g} vs {e} in {got:?}"
            );
        }
    }
}

fn fmt_list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:.5}")).collect();
    format!("[{}]", items.join(", "))
}

fn inputs_trace(step: &evo_state::Step) -> String {
    let inputs = step.psi_inputs().unwrap();
    let mut out = format!("t={:.4} frame={:?}\n", step.time(), step.frame());
    for (i, row) in inputs.chunks(6).enumerate() {
        let row: Vec<f64> = row.iter().map(|&x| x as f64).collect();
        out += &format!(
            "  row {i}: psi inputs [m, |v2|, |v1|, theta] = {}\n",
            fmt_list(&row)
        );
    }
    out
}
