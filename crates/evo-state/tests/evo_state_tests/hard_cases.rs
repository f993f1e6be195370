//! Hard cases: zero motion, a 180° reversal, colinear vectors whose cosine rounds above 1,
//! values beyond f16 range, non-finite inputs, stale steps, and a proptest that finite inputs
//! never give NaN or Inf.

use crate::common;

use common::*;
use evo_state::{EvoConfig, EvoError, Gain, RowPlan, Storage};
use proptest::prelude::*;

/// Commits the given positions (D = 3) at frames 0..3 and returns θ at frame 3. Frames are
/// committed in reverse order, so each commit sees no history and stores exactly z.
fn theta_after(positions: [[f32; 3]; 3], config: EvoConfig) -> f32 {
    let mut st = state(
        EvoConfig {
            layout: position_only(),
            ..config
        },
        uniform_frames(5),
        1,
    );
    for (k, p) in positions.iter().enumerate().rev() {
        let step = train(&mut st, k, p);
        assert_eq!(step.history().len, 0);
    }
    let step = st.forward(st.frames().times()[3], &[0.0; 3]).unwrap();
    step.stats().unwrap()[0].theta
}

#[test]
fn zero_motion_has_zero_angle() {
    // Still: |v1| = |v2| = 0 < floor; the paper's formula would give π/2.
    assert_eq!(theta_after([[1.0, 2.0, 3.0]; 3], EvoConfig::default()), 0.0);
    // Moving, then still: one velocity below the floor.
    assert_eq!(
        theta_after(
            [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
            EvoConfig::default()
        ),
        0.0
    );
    // Motion just below the floor of a large scene (extent 100: floor 1e-4) counts as still.
    let big = EvoConfig {
        extent: 100.0,
        ..EvoConfig::default()
    };
    assert_eq!(
        theta_after([[0.0; 3], [5e-5, 0.0, 0.0], [0.0; 3]], big),
        0.0
    );
    // ... and above it the reversal is seen (DESIGN §4.7's ε matters at this scale).
    let theta = theta_after([[0.0; 3], [5e-3, 0.0, 0.0], [0.0; 3]], big);
    let v = 5e-3f32 as f64;
    let expected = (-(v * v) / (v * v + 1e-6)).acos() as f32;
    assert!((theta - expected).abs() < 1e-5, "{theta} vs {expected}");
    assert!(theta > 2.5);
}

#[test]
fn reversal_gives_pi() {
    let theta = theta_after([[0.0; 3], [1.0, 1.0, 0.0], [0.0; 3]], EvoConfig::default());
    // cos = -2 / (2 + 1e-6): θ = π - ~1e-3.
    let expected = (-2.0f64 / (2.0 + 1e-6)).acos() as f32;
    assert!((theta - expected).abs() < 1e-6, "{theta} vs {expected}");
    assert!((theta - std::f32::consts::PI).abs() < 2e-3);
}

#[test]
fn colinear_vectors_whose_cosine_rounds_above_one() {
    // Positions 0, v, 4v (exact in f32): v2 = v, v1 = 3v exactly. Search for v where DESIGN §4.7's
    // cosine <v2, v1> / (|v2||v1| + 1e-6), computed as the implementation does (f64), rounds
    // above 1; the clamp must then give θ = 0 rather than NaN.
    let mut found = 0;
    for i in 1..20000u32 {
        let v = [1.0e4f32 * i as f32 + 0.37, 3.1e4 * i as f32, 7.3e3];
        let p2 = [4.0 * v[0], 4.0 * v[1], 4.0 * v[2]];
        let (mut n1, mut n2, mut dot) = (0.0f64, 0.0f64, 0.0f64);
        for j in 0..3 {
            let a = p2[j] as f64 - v[j] as f64;
            let b = v[j] as f64;
            n1 += a * a;
            n2 += b * b;
            dot += a * b;
        }
        let cos = dot / (n1.sqrt() * n2.sqrt() + 1e-6);
        if cos > 1.0 {
            found += 1;
            assert!(cos.acos().is_nan());
            let theta = theta_after([[0.0; 3], v, p2], EvoConfig::default());
            assert_eq!(theta, 0.0, "v = {v:?}");
        }
    }
    assert!(found > 0, "no colinear pair with cosine above 1 found");
}

#[test]
fn values_beyond_f16_range_saturate_and_are_counted() {
    let config = EvoConfig {
        storage: Storage::F16,
        layout: position_only(),
        ..EvoConfig::default()
    };
    let mut st = state(config, uniform_frames(4), 2);
    train(&mut st, 0, &[1e5, -1e6, 3.0, 65504.0, 65520.0, -70000.0]);
    assert_eq!(st.saturations(), 4);
    let buffer = st.buffer().unwrap();
    assert_eq!(buffer.row(0, 0), vec![65504.0, -65504.0, 3.0]);
    assert_eq!(buffer.row(0, 1), vec![65504.0, 65504.0, -65504.0]);
    // Later steps from saturated history stay finite.
    for k in 1..4 {
        let step = train(&mut st, k, &[1e30, -1e30, 0.0, 1e30, 0.0, 0.0]);
        assert!(step.corrected().iter().all(|v| v.is_finite()));
        let back = st
            .backward(
                &step,
                &[1e30, -1e30, 0.0, 1e30, 0.0, 0.0],
                &[1.0; 6],
                &[1.0; 2],
            )
            .unwrap();
        assert!(back.dz.iter().all(|v| v.is_finite()));
        assert!(back.dpsi.iter().flatten().all(|v| v.is_finite()));
    }
    assert!(st.saturations() > 4);
    // The per-frame memory, stored as f16 beside the buffer, saturates the same way:
    // m = 0.1·(1e30 - prior) at frame 2.
    let memory = st.memory().unwrap();
    assert_eq!(memory.row(2, 0)[0], 65504.0);
    assert!((0..4).all(|k| memory.row(k, 1).iter().all(|v| v.abs() <= 65504.0)));
}

#[test]
fn non_finite_inputs_are_rejected_naming_the_gaussian() {
    let mut st = state(EvoConfig::default(), uniform_frames(4), 5);
    let d = st.dim();
    let mut z = vec![0.1f32; 5 * d];
    z[3 * d + 2] = f32::NAN;
    let err = st.forward(0.0, &z).unwrap_err();
    assert!(
        matches!(
            err,
            EvoError::NonFinite {
                row: 3,
                component: 2,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("Gaussian 3"), "{err}");
    z[3 * d + 2] = f32::INFINITY;
    assert!(st.forward(0.0, &z).is_err());
    z[3 * d + 2] = 0.0;
    let step = train(&mut st, 0, &z);
    let mut opacity = vec![1.0f32; 5];
    opacity[4] = f32::NAN;
    let err = st.backward(&step, &z, &z, &opacity).unwrap_err();
    assert!(
        err.to_string().contains("opacity") && err.to_string().contains("Gaussian 4"),
        "{err}"
    );
    let err = st.forward(0.0, &z[1..]).unwrap_err();
    assert!(matches!(err, EvoError::Length { .. }), "{err}");
    assert!(matches!(
        st.forward(f32::NAN, &z),
        Err(EvoError::NonFiniteTime(_))
    ));
}

#[test]
fn stale_steps_cannot_commit() {
    let mut st = state(EvoConfig::default(), uniform_frames(4), 3);
    let d = st.dim();
    let step = st.forward(0.0, &vec![0.0; 3 * d]).unwrap();
    st.apply_rows(&RowPlan {
        kept: vec![0, 1, 2],
        parent_from_new: vec![1],
    })
    .unwrap();
    assert!(matches!(st.commit(&step), Err(EvoError::StaleStep { .. })));
    // Even an identity plan makes earlier steps stale.
    let step = st.forward(0.0, &vec![0.0; 4 * d]).unwrap();
    st.apply_rows(&RowPlan::identity(4)).unwrap();
    assert!(matches!(st.commit(&step), Err(EvoError::StaleStep { .. })));
}

fn finite_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        -10.0f32..10.0,
        -1e6f32..1e6,
        Just(0.0f32),
        Just(1e30f32),
        Just(-3e38f32),
        Just(f32::MIN_POSITIVE),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any finite observations, opacities and render gradients, in any storage and gain mode,
    /// in any frame order: every output is finite.
    #[test]
    fn finite_inputs_never_give_nan_or_inf(
        zs in proptest::collection::vec(proptest::collection::vec(finite_f32(), 3 * 10), 6),
        order in Just((0..6usize).collect::<Vec<_>>()).prop_shuffle(),
        f16 in any::<bool>(),
        fixed in proptest::option::of(0.0f32..=1.0),
        g in proptest::collection::vec(-1e3f32..1e3, 3 * 10),
        opacity in proptest::collection::vec(0.0f32..=1.0, 3),
        query in -1.0f32..3.0,
    ) {
        let config = EvoConfig {
            storage: if f16 { Storage::F16 } else { Storage::F32 },
            gain: fixed.map_or(Gain::Learned, Gain::Fixed),
            ..EvoConfig::default()
        };
        let mut st = state(config, uniform_frames(6), 3);
        for &k in &order {
            let step = train(&mut st, k, &zs[k]);
            prop_assert!(step.corrected().iter().all(|v| v.is_finite()));
            prop_assert!(step.prior().into_iter().flatten().all(|v| v.is_finite()));
            prop_assert!(step.stats().into_iter().flatten().all(|s| s.theta.is_finite() && s.speed_last.is_finite()));
            let back = st.backward(&step, &zs[k], &g, &opacity).unwrap();
            prop_assert!(back.dz.iter().all(|v| v.is_finite()));
            prop_assert!(back.dpsi.iter().flatten().all(|v| v.is_finite()));
            prop_assert!(back.losses.sup.is_finite() && back.losses.prior.is_finite());
            let memory = st.memory().unwrap();
            prop_assert!((0..6).all(|f| (0..3).all(|i| memory.row(f, i).iter().all(|v| v.is_finite()))));
            prop_assert!(step.psi_inputs().into_iter().flatten().all(|v| v.is_finite()));
            prop_assert!(st.input_norm().rms().into_iter().flatten().all(|v| v.is_finite()));
        }
        let step = st.forward(query, &zs[0]).unwrap();
        prop_assert!(step.corrected().iter().all(|v| v.is_finite()));
    }
}

/// Zero and one Gaussian, including pruning every row mid-training.
#[test]
fn zero_and_one_gaussian() {
    for rows in [0usize, 1] {
        let mut st = state(EvoConfig::default(), uniform_frames(6), rows);
        let d = st.dim();
        for k in 0..5 {
            let z = vec![k as f32; rows * d];
            let step = train(&mut st, k, &z);
            let back = st
                .backward(&step, &z, &vec![0.1; rows * d], &vec![1.0; rows])
                .unwrap();
            assert_eq!(back.dz.len(), rows * d);
            assert!(back.losses.sup.is_finite() && back.losses.prior.is_finite());
            assert!(back.dpsi.iter().flatten().all(|g| g.is_finite()));
        }
    }
    let mut st = state(EvoConfig::default(), uniform_frames(6), 3);
    let d = st.dim();
    for k in 0..4 {
        train(&mut st, k, &vec![k as f32; 3 * d]);
    }
    st.apply_rows(&RowPlan::prune(&[false, false, false]))
        .unwrap();
    assert_eq!((st.rows(), st.memory_bytes(), st.buffer_bytes()), (0, 0, 0));
    let step = train(&mut st, 4, &[]);
    assert_eq!(step.history().len, 3);
}

/// The densification cues of a step: none before there is a prior (residual) or statistics
/// (θ); a residual measured on the position part relative to the extent, or on the whole
/// vector unscaled without a position component; wrong lengths and unusable extents refused.
#[test]
fn residual_cues_need_a_prior_and_refuse_bad_inputs() {
    let rotation_only = evo_state::Layout {
        rotation: true,
        ..evo_state::Layout::from_bits(0).unwrap()
    };
    for (layout, scale) in [(position_only(), 0.5), (rotation_only, 1.0)] {
        let config = EvoConfig {
            layout,
            gain: Gain::Fixed(0.5),
            ..EvoConfig::default()
        };
        let mut st = state(config, uniform_frames(4), 1);
        let d = layout.dim();
        let first = train(&mut st, 0, &vec![0.0; d]);
        assert_eq!(
            first.residual_norms(&vec![0.0; d], layout, 2.0).unwrap(),
            None
        );
        assert_eq!(first.thetas(), None);
        train(&mut st, 1, &vec![0.1; d]);
        let z = vec![1.0; d];
        let step = st.forward(st.frames().times()[2], &z).unwrap();
        let prior = step.prior().unwrap();
        let want = z
            .iter()
            .zip(prior)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f32>()
            .sqrt()
            * scale;
        let got = step.residual_norms(&z, layout, 2.0).unwrap().unwrap();
        assert!(
            (got[0] - want).abs() < 1e-6,
            "`{layout}`: {got:?} vs {want}"
        );
        assert_eq!(step.thetas(), None, "θ needs three frames of history");
        let e = step.residual_norms(&z[1..], layout, 2.0).unwrap_err();
        assert!(
            matches!(
                e,
                EvoError::Length {
                    what: "observation z",
                    ..
                }
            ),
            "{e}"
        );
        for extent in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let e = step.residual_norms(&z, layout, extent).unwrap_err();
            assert!(matches!(e, EvoError::Extent(_)), "{e}");
        }
    }
}
