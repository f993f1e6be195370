//! Encoders: finite-difference gradients, exact endpoints, clamping, f16 bounds, snapshots.

use crate::common;

use common::{check_fd, dot, vals};
use tiny_nn::encoding::bspline::basis;
use tiny_nn::{BSplineConfig, PlaneCombine, Precision, Sinusoidal, TriPlaneConfig};

#[test]
fn sinusoidal_follows_the_d3dgs_ordering() {
    let enc = Sinusoidal::new(2, 2).unwrap();
    assert_eq!(enc.output_width(), 10);
    let (a, b) = (0.3f32, -1.2f32);
    let y = enc.forward(&[a, b], 1).unwrap();
    let want = [
        a,
        b,
        a.sin(),
        b.sin(),
        a.cos(),
        b.cos(),
        (2.0 * a).sin(),
        (2.0 * b).sin(),
        (2.0 * a).cos(),
        (2.0 * b).cos(),
    ];
    assert_eq!(y, want);
    assert_eq!(Sinusoidal::new(3, 10).unwrap().output_width(), 63);
    assert_eq!(Sinusoidal::new(1, 6).unwrap().output_width(), 13);
}

#[test]
fn sinusoidal_gradient_matches_finite_differences() {
    let enc = Sinusoidal::new(3, 6).unwrap();
    let rows = 1100; // more than one block of 1024
    let x = vals(rows * 3, 1, 1.0);
    let c = vals(rows * enc.output_width(), 2, 1.0);
    let g = enc.backward(&x, &c, rows).unwrap();
    // Check a subset of rows (each coordinate only affects its own row).
    let sub = 5;
    let xs = &x[..sub * 3];
    check_fd("sinusoidal input", xs, &g[..sub * 3], 1e-3, 2e-3, |xx| {
        dot(
            &enc.forward(xx, sub).unwrap(),
            &c[..sub * enc.output_width()],
        )
    });
    assert!(enc.forward(&x[..5], 2).is_err());
    assert!(enc.forward(&[], 0).unwrap().is_empty());
}

fn triplane_fd(combine: PlaneCombine) {
    let tp = TriPlaneConfig::new(3, &[3, 5], combine)
        .bounds([-2.0, 0.0, 1.0], [2.0, 1.0, 3.0])
        .seed(4)
        .build()
        .unwrap();
    let rows = 6;
    // Inside the box, away from texel lines (h = 1e-3 does not cross them for these seeds).
    let mut pos = Vec::new();
    for (i, u) in vals(rows * 3, 7, 0.9).iter().enumerate() {
        let a = i % 3;
        let (lo, hi) = ([-2.0f32, 0.0, 1.0][a], [2.0f32, 1.0, 3.0][a]);
        pos.push(lo + (u + 1.0) * 0.5 * (hi - lo));
    }
    let c = vals(rows * tp.output_width(), 8, 1.0);
    let (_, cache) = tp.forward(&pos, rows).unwrap();
    let g = tp.backward(&cache, &c, true).unwrap();
    let params = tp.params().to_vec_f32();
    let mut tp2 = tp.clone();
    check_fd("tri-plane params", &params, &g.params, 1e-2, 2e-3, |pp| {
        tp2.set_params(pp).unwrap();
        dot(&tp2.forward(&pos, rows).unwrap().0, &c)
    });
    check_fd(
        "tri-plane positions",
        &pos,
        &g.positions.unwrap(),
        1e-3,
        5e-3,
        |pp| dot(&tp.forward(pp, rows).unwrap().0, &c),
    );
}

#[test]
fn triplane_concat_gradients_match_finite_differences() {
    triplane_fd(PlaneCombine::Concat);
}

#[test]
fn triplane_product_gradients_match_finite_differences() {
    triplane_fd(PlaneCombine::Product);
}

#[test]
fn triplane_clamps_outside_the_box_with_zero_position_gradient() {
    let tp = TriPlaneConfig::new(2, &[4], PlaneCombine::Product)
        .bounds([0.0; 3], [1.0; 3])
        .seed(1)
        .build()
        .unwrap();
    let outside = [1.7f32, -3.0, 0.4];
    let clamped = [1.0f32, 0.0, 0.4];
    let (yo, cache) = tp.forward(&outside, 1).unwrap();
    let (yc, _) = tp.forward(&clamped, 1).unwrap();
    assert_eq!(yo, yc);
    let g = tp.backward(&cache, &[1.0, 1.0], true).unwrap();
    let gp = g.positions.unwrap();
    assert_eq!(gp[0], 0.0);
    assert_eq!(gp[1], 0.0);
    assert!(gp[2] != 0.0);
    // Exactly on the upper corner: the last texel.
    let (y, _) = tp.forward(&[1.0, 1.0, 1.0], 1).unwrap();
    let p = tp.params().to_vec_f32();
    let (last, c) = ((4 * 4 - 1) * 2, 2);
    let stride = 4 * 4 * c;
    for ch in 0..c {
        let want = p[last + ch] * p[stride + last + ch] * p[2 * stride + last + ch];
        assert!(
            (y[ch] - want).abs() <= 1e-6 * want.abs(),
            "{} vs {want}",
            y[ch]
        );
    }
    assert!(tp.forward(&[f32::NAN, 0.0, 0.0], 1).is_err());
    assert!(
        TriPlaneConfig::new(2, &[1], PlaneCombine::Concat)
            .build()
            .is_err()
    );
    assert!(
        TriPlaneConfig::new(2, &[4], PlaneCombine::Concat)
            .bounds([0.0; 3], [0.0, 1.0, 1.0])
            .build()
            .is_err()
    );
}

#[test]
fn triplane_zero_one_and_many_rows() {
    let tp = TriPlaneConfig::new(4, &[8], PlaneCombine::Concat)
        .build()
        .unwrap();
    let (y, cache) = tp.forward(&[], 0).unwrap();
    assert!(y.is_empty());
    let g = tp.backward(&cache, &[], true).unwrap();
    assert!(g.params.iter().all(|&v| v == 0.0));
    // 1500 rows (not a multiple of the 1024-row block) agree row by row with one-row calls.
    let pos = vals(1500 * 3, 3, 1.2);
    let (y, _) = tp.forward(&pos, 1500).unwrap();
    for r in [0usize, 1023, 1024, 1499] {
        let (y1, _) = tp.forward(&pos[r * 3..r * 3 + 3], 1).unwrap();
        assert_eq!(&y[r * 12..r * 12 + 12], &y1[..]);
    }
}

#[test]
fn triplane_f16_agrees_with_f32() {
    let a = TriPlaneConfig::new(8, &[16, 32], PlaneCombine::Product).seed(3);
    let t32 = a.clone().build().unwrap();
    let t16 = a.precision(Precision::F16).build().unwrap();
    let pos = vals(2000 * 3, 5, 1.0);
    let (y32, _) = t32.forward(&pos, 2000).unwrap();
    let (y16, _) = t16.forward(&pos, 2000).unwrap();
    let err = y32
        .iter()
        .zip(&y16)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    // Plane values in (0.1, 0.5) rounded to f16 (rel. 2^-11) in a product of three.
    assert!(err < 2e-4, "max error {err}");
}

#[test]
fn bspline_is_exact_at_both_ends() {
    let m = 6;
    let sp = BSplineConfig::new(m, 2).seed(9).build().unwrap();
    let p = sp.params().to_vec_f32();
    let ctrl = |i: usize, x: usize| p[i * 2 + x];
    let (y, _) = sp.forward(&[0.0, 1.0]).unwrap();
    for x in 0..2 {
        let at0 = (ctrl(0, x) + 4.0 * ctrl(1, x) + ctrl(2, x)) / 6.0;
        let at1 = (ctrl(m - 3, x) + 4.0 * ctrl(m - 2, x) + ctrl(m - 1, x)) / 6.0;
        assert!((y[x] - at0).abs() < 1e-7, "{} vs {at0}", y[x]);
        assert!((y[2 + x] - at1).abs() < 1e-7, "{} vs {at1}", y[2 + x]);
    }
    assert_eq!(sp.segment(0.0), (0, 0.0, 3.0));
    assert_eq!(sp.segment(1.0), (2, 1.0, 3.0));
    // Outside: clamped, no time gradient.
    let (yo, c) = sp.forward(&[-0.5, 1.5]).unwrap();
    assert_eq!(yo, y);
    let g = sp.backward(&c, &[1.0; 4], true).unwrap();
    assert_eq!(g.times.unwrap(), vec![0.0, 0.0]);
    assert!(sp.forward(&[0.5, f32::INFINITY]).is_err());
    assert!(BSplineConfig::new(3, 2).build().is_err());
}

#[test]
fn bspline_basis_is_a_partition_of_unity_and_continuous() {
    for i in 0..=20 {
        let u = i as f32 / 20.0;
        let s: f32 = basis(u).iter().sum();
        assert!((s - 1.0).abs() < 1e-6);
    }
    let sp = BSplineConfig::new(8, 3).seed(2).build().unwrap();
    let knot = 2.0 / 5.0;
    let (y, _) = sp.forward(&[knot - 1e-6, knot + 1e-6]).unwrap();
    for x in 0..3 {
        assert!((y[x] - y[3 + x]).abs() < 1e-5);
    }
}

#[test]
fn bspline_gradients_match_finite_differences() {
    let sp = BSplineConfig::new(7, 5).seed(3).build().unwrap();
    let ts: Vec<f32> = vals(1300, 4, 0.49).iter().map(|v| v + 0.5).collect();
    let c = vals(1300 * 5, 5, 1.0);
    let (_, cache) = sp.forward(&ts).unwrap();
    let g = sp.backward(&cache, &c, true).unwrap();
    let mut sp2 = sp.clone();
    let p = sp.params().to_vec_f32();
    check_fd("B-spline params", &p, &g.params, 1e-2, 2e-3, |pp| {
        sp2.set_params(pp).unwrap();
        dot(&sp2.forward(&ts).unwrap().0, &c)
    });
    let sub = 40;
    check_fd(
        "B-spline times",
        &ts[..sub],
        &g.times.unwrap()[..sub],
        1e-3,
        5e-3,
        |tt| dot(&sp.forward(tt).unwrap().0, &c[..sub * 5]),
    );
}

#[test]
fn small_outputs_snapshot() {
    let enc = Sinusoidal::new(1, 3).unwrap();
    let s = enc.forward(&[0.5, -1.0], 2).unwrap();
    let mut sp = BSplineConfig::new(5, 2).build().unwrap();
    sp.set_params(&[0.0, 1.0, 1.0, 2.0, 2.0, 0.0, 3.0, -1.0, 6.0, 0.0])
        .unwrap();
    let (b, _) = sp.forward(&[0.0, 0.25, 0.5, 1.0]).unwrap();
    let mut tp = TriPlaneConfig::new(1, &[2], PlaneCombine::Concat)
        .build()
        .unwrap();
    tp.set_params(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0])
        .unwrap();
    let (t, _) = tp.forward(&[0.0, 0.0, 0.0, 1.0, -1.0, 0.5], 2).unwrap();
    let fmt = |v: &[f32]| {
        v.iter()
            .map(|x| format!("{x:.6}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    insta::assert_snapshot!(format!(
        "sinusoidal L=3 at 0.5, -1.0:\n{}\n{}\nB-spline M=5 E=2 at t=0, 0.25, 0.5, 1:\n{}\ntri-plane C=1 R=2 concat at (0,0,0), (1,-1,0.5):\n{}",
        fmt(&s[..7]),
        fmt(&s[7..]),
        fmt(&b),
        fmt(&t)
    ));
}

mod props {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        #[test]
        fn triplane_output_at_any_position_is_that_of_the_clamped_position(
            x in -1e6f32..1e6, y in -5.0f32..5.0, z in -5.0f32..5.0,
            combine in prop_oneof![Just(PlaneCombine::Concat), Just(PlaneCombine::Product)],
        ) {
            let (lo, hi) = ([-1.0f32, 0.0, 2.0], [1.0f32, 2.0, 3.0]);
            let tp = TriPlaneConfig::new(3, &[4, 7], combine).bounds(lo, hi).seed(5).build().unwrap();
            let p = [x, y, z];
            let clamped: Vec<f32> = (0..3).map(|a| p[a].clamp(lo[a], hi[a])).collect();
            let (yp, cache) = tp.forward(&p, 1).unwrap();
            let (yc, _) = tp.forward(&clamped, 1).unwrap();
            prop_assert!(yp.iter().all(|v| v.is_finite()));
            for (a, b) in yp.iter().zip(&yc) {
                prop_assert!((a - b).abs() <= 1e-6 * (1.0 + b.abs()));
            }
            let w = tp.output_width();
            let g = tp.backward(&cache, &vec![1.0; w], true).unwrap();
            let gp = g.positions.unwrap();
            for a in 0..3 {
                if p[a] < lo[a] || p[a] > hi[a] {
                    prop_assert_eq!(gp[a], 0.0);
                }
                prop_assert!(gp[a].is_finite());
            }
            prop_assert!(g.params.iter().all(|v| v.is_finite()));
        }

        #[test]
        fn bspline_at_any_time_is_that_of_the_clamped_time(t in -10.0f32..10.0, m in 4usize..12) {
            let sp = BSplineConfig::new(m, 3).seed(m as u64).build().unwrap();
            let (y, _) = sp.forward(&[t]).unwrap();
            let (yc, _) = sp.forward(&[t.clamp(0.0, 1.0)]).unwrap();
            prop_assert_eq!(y, yc);
            let (k, u, _) = sp.segment(t);
            prop_assert!(k + 3 < m);
            prop_assert!((0.0..=1.0).contains(&u));
        }
    }
}
