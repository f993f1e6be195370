//! HexPlane (the tri-plane encoder with a time axis): an f64 reference written from the
//! documented layout, f64 finite differences, 4DGaussians' sizes and initialisation, clamping of
//! times, and the three regularisers.

// The f64 references index planes and channels by position, as the formulas are written.
#![allow(clippy::needless_range_loop)]

use crate::common;

use common::{check_fd, dot, vals};
use tiny_nn::{
    ObservationConfig, ObservationNet, PlaneCombine, PlaneRegulariser, Precision, TimeAxis,
    TriPlane, TriPlaneConfig,
};

fn hex(combine: PlaneCombine, seed: u64) -> TriPlane {
    let mut tp = TriPlaneConfig::new(3, &[3, 5], combine)
        .bounds([-2.0, 0.0, 1.0], [2.0, 1.0, 3.0])
        .time(TimeAxis::new(4, -0.5, 1.5))
        .seed(seed)
        .build()
        .unwrap();
    // Space-time planes away from 1 so that every plane matters in products.
    let p: Vec<f32> = vals(tp.param_count(), seed + 10, 0.5)
        .iter()
        .map(|v| v + 0.8)
        .collect();
    tp.set_params(&p).unwrap();
    tp
}

/// The encoding of one row `(x, y, z, t)` in f64, from the documentation: normalise and clamp to
/// [-1, 1], bilinear sample at `(q + 1)/2 · (R - 1)` in `[R_b][R_a][C]` planes, product or
/// concatenation per scale.
fn reference(tp: &TriPlane, params: &[f64], row: &[f64]) -> Vec<f64> {
    let cfg = tp.config();
    let t = cfg.time.as_ref().unwrap();
    let lo = [cfg.box_min[0], cfg.box_min[1], cfg.box_min[2], t.min];
    let hi = [cfg.box_max[0], cfg.box_max[1], cfg.box_max[2], t.max];
    let q: Vec<f64> = (0..4)
        .map(|a| (2.0 * (row[a] - lo[a] as f64) / (hi[a] - lo[a]) as f64 - 1.0).clamp(-1.0, 1.0))
        .collect();
    let c = cfg.channels;
    let mut out = Vec::new();
    for r in 0..cfg.resolutions.len() {
        let mut prod = vec![1f64; c];
        for k in 0..6 {
            let (a, b) = tp.plane_axes(k);
            let (ra, rb) = (tp.axis_resolution(r, a), tp.axis_resolution(r, b));
            let fa = (q[a] + 1.0) / 2.0 * (ra - 1) as f64;
            let fb = (q[b] + 1.0) / 2.0 * (rb - 1) as f64;
            let ia = (fa.floor() as usize).min(ra - 2);
            let ib = (fb.floor() as usize).min(rb - 2);
            let (ua, ub) = (fa - ia as f64, fb - ib as f64);
            let off = tp.plane_offset(r, k);
            let texel = |i: usize, j: usize, ch: usize| params[off + (j * ra + i) * c + ch];
            for ch in 0..c {
                let v = (1.0 - ua) * (1.0 - ub) * texel(ia, ib, ch)
                    + ua * (1.0 - ub) * texel(ia + 1, ib, ch)
                    + (1.0 - ua) * ub * texel(ia, ib + 1, ch)
                    + ua * ub * texel(ia + 1, ib + 1, ch);
                match cfg.combine {
                    PlaneCombine::Concat => out.push(v),
                    PlaneCombine::Product => prod[ch] *= v,
                }
            }
        }
        if cfg.combine == PlaneCombine::Product {
            out.extend(prod);
        }
    }
    out
}

fn ref_loss(tp: &TriPlane, params: &[f64], x: &[f64], c: &[f32]) -> f64 {
    let w = tp.output_width();
    x.chunks_exact(4)
        .enumerate()
        .map(|(i, row)| {
            reference(tp, params, row)
                .iter()
                .zip(&c[i * w..(i + 1) * w])
                .map(|(y, &ci)| y * ci as f64)
                .sum::<f64>()
        })
        .sum()
}

/// Rows (x, y, z, t) inside the box and the time range.
fn rows_inside(tp: &TriPlane, rows: usize, seed: u64) -> Vec<f32> {
    let cfg = tp.config();
    let t = cfg.time.as_ref().unwrap();
    let lo = [cfg.box_min[0], cfg.box_min[1], cfg.box_min[2], t.min];
    let hi = [cfg.box_max[0], cfg.box_max[1], cfg.box_max[2], t.max];
    vals(rows * 4, seed, 0.93)
        .iter()
        .enumerate()
        .map(|(i, u)| lo[i % 4] + (u + 1.0) * 0.5 * (hi[i % 4] - lo[i % 4]))
        .collect()
}

#[test]
fn hexplane_matches_the_f64_reference_and_its_finite_differences() {
    for combine in [PlaneCombine::Product, PlaneCombine::Concat] {
        let tp = hex(combine, 3);
        assert_eq!(tp.dims(), 4);
        assert_eq!(tp.planes_per_scale(), 6);
        let rows = 7;
        let x = rows_inside(&tp, rows, 4);
        let (y, cache) = tp.forward(&x, rows).unwrap();
        let params: Vec<f64> = tp.params().to_vec_f32().iter().map(|&v| v as f64).collect();
        let x64: Vec<f64> = x.iter().map(|&v| v as f64).collect();
        let w = tp.output_width();
        for i in 0..rows {
            let want = reference(&tp, &params, &x64[i * 4..i * 4 + 4]);
            for (a, b) in y[i * w..(i + 1) * w].iter().zip(&want) {
                assert!(
                    (*a as f64 - b).abs() < 1e-5,
                    "{combine:?} row {i}: {a} vs {b}"
                );
            }
        }
        let c = vals(rows * w, 8, 1.0);
        let g = tp.backward(&cache, &c, true).unwrap();
        // Parameters (multilinear: a unit step is exact up to rounding).
        let mut pp = params.clone();
        for j in 0..pp.len() {
            let p0 = pp[j];
            pp[j] = p0 + 0.5;
            let lp = ref_loss(&tp, &pp, &x64, &c);
            pp[j] = p0 - 0.5;
            let lm = ref_loss(&tp, &pp, &x64, &c);
            pp[j] = p0;
            let fd = lp - lm;
            assert!(
                (g.params[j] as f64 - fd).abs() <= 1e-5 * (1.0 + fd.abs()),
                "{combine:?} param {j}: {} vs {fd}",
                g.params[j]
            );
        }
        // Inputs, time included (central differences in f64; rows avoid texel lines by
        // far more than h).
        let gp = g.positions.unwrap();
        let h = 1e-7;
        let mut xx = x64.clone();
        for j in 0..xx.len() {
            xx[j] = x64[j] + h;
            let lp = ref_loss(&tp, &params, &xx, &c);
            xx[j] = x64[j] - h;
            let lm = ref_loss(&tp, &params, &xx, &c);
            xx[j] = x64[j];
            let fd = (lp - lm) / (2.0 * h);
            assert!(
                (gp[j] as f64 - fd).abs() <= 1e-4 * (1.0 + fd.abs()),
                "{combine:?} input {j}: {} vs {fd}",
                gp[j]
            );
        }
    }
}

#[test]
fn hexplane_has_4dgaussians_sizes_and_initialisation() {
    // 4DGaussians' D-NeRF jumpingjacks: 32 channels, space 64 × multires [1, 2], time 100.
    let tp = TriPlaneConfig::new(32, &[64, 128], PlaneCombine::Product)
        .time(TimeAxis::new(100, -1.0, 1.0))
        .build()
        .unwrap();
    assert_eq!(tp.output_width(), 64);
    let per_scale = |r: usize| 3 * r * r + 3 * r * 100;
    assert_eq!(tp.param_count(), (per_scale(64) + per_scale(128)) * 32);
    let p = tp.params().to_vec_f32();
    for r in 0..2 {
        for k in 0..6 {
            let (a, b) = tp.plane_axes(k);
            let n = tp.axis_resolution(r, a) * tp.axis_resolution(r, b) * 32;
            let plane = &p[tp.plane_offset(r, k)..tp.plane_offset(r, k) + n];
            if b == 3 {
                assert!(plane.iter().all(|&v| v == 1.0), "scale {r} plane {k}");
            } else {
                assert!(plane.iter().all(|&v| (0.1..0.5).contains(&v)));
            }
        }
    }
    assert_eq!(
        (0..6).map(|k| tp.plane_axes(k)).collect::<Vec<_>>(),
        [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    );
    // With the space-time planes at 1 the product is that of the space planes alone.
    let mut tri = TriPlaneConfig::new(32, &[64, 128], PlaneCombine::Product)
        .build()
        .unwrap();
    let tpr = &tp;
    let space: Vec<f32> = (0..2)
        .flat_map(|r| {
            [0, 1, 3].into_iter().flat_map(move |k| {
                let (a, b) = tpr.plane_axes(k);
                let n = tpr.axis_resolution(r, a) * tpr.axis_resolution(r, b) * 32;
                let off = tpr.plane_offset(r, k);
                (off..off + n).collect::<Vec<_>>()
            })
        })
        .map(|i| p[i])
        .collect();
    tri.set_params(&space).unwrap();
    let x = [0.3f32, -0.4, 0.9];
    let (yt, _) = tri.forward(&x, 1).unwrap();
    let (yh, _) = tp.forward(&[0.3, -0.4, 0.9, 0.37], 1).unwrap();
    assert_eq!(yt, yh);
}

#[test]
fn times_outside_the_axis_clamp_with_zero_gradient() {
    let tp = hex(PlaneCombine::Product, 5);
    let w = tp.output_width();
    for (t, tc) in [(-3.0f32, -0.5f32), (7.0, 1.5)] {
        let (y, cache) = tp.forward(&[0.1, 0.5, 2.0, t], 1).unwrap();
        let (yc, _) = tp.forward(&[0.1, 0.5, 2.0, tc], 1).unwrap();
        assert_eq!(y, yc);
        let g = tp.backward(&cache, &vec![1.0; w], true).unwrap();
        let gp = g.positions.unwrap();
        assert_eq!(gp[3], 0.0);
        assert!(gp[..3].iter().all(|&v| v != 0.0));
    }
    assert!(tp.forward(&[0.1, 0.5, 2.0, f32::NAN], 1).is_err());
    assert!(tp.forward(&[0.1, 0.5, 2.0], 1).is_err());
    let bad = |axis: TimeAxis| {
        TriPlaneConfig::new(2, &[4], PlaneCombine::Product)
            .time(axis)
            .build()
            .is_err()
    };
    assert!(bad(TimeAxis::new(1, 0.0, 1.0)));
    assert!(bad(TimeAxis::new(4, 1.0, 1.0)));
    assert!(bad(TimeAxis {
        init: f32::NAN,
        ..TimeAxis::new(4, 0.0, 1.0)
    }));
}

#[test]
fn regularisers_match_their_formulas_and_finite_differences() {
    let tp = hex(PlaneCombine::Product, 9);
    let n = tp.param_count();
    let p = tp.params().to_vec_f32();
    for which in [
        PlaneRegulariser::SpaceSmoothness,
        PlaneRegulariser::TimeSmoothness,
        PlaneRegulariser::TimeL1,
    ] {
        let weight = 0.7f32;
        let mut g = vec![0f32; n];
        let value = tp.regularise(which, weight, &mut g).unwrap();
        // The formula, plane by plane.
        let mut want = 0f64;
        for r in 0..2 {
            for k in 0..6 {
                let (a, b) = tp.plane_axes(k);
                let time_plane = b == 3;
                if time_plane == (which == PlaneRegulariser::SpaceSmoothness) {
                    continue;
                }
                let (ra, rb) = (tp.axis_resolution(r, a), tp.axis_resolution(r, b));
                let off = tp.plane_offset(r, k);
                let at = |i: usize, j: usize, ch: usize| p[off + (j * ra + i) * 3 + ch] as f64;
                let (mut s, mut cnt) = (0f64, 0usize);
                for j in 0..rb {
                    for i in 0..ra {
                        for ch in 0..3 {
                            if which == PlaneRegulariser::TimeL1 {
                                s += (1.0 - at(i, j, ch)).abs();
                                cnt += 1;
                            } else if j + 2 < rb {
                                let d2 = at(i, j + 2, ch) - 2.0 * at(i, j + 1, ch) + at(i, j, ch);
                                s += d2 * d2;
                                cnt += 1;
                            }
                        }
                    }
                }
                want += s / cnt as f64;
            }
        }
        want *= weight as f64;
        assert!(want > 0.0);
        assert!(
            (value - want).abs() <= 1e-6 * want,
            "{which:?}: {value} vs {want}"
        );
        // The gradient touches only the planes the regulariser reads.
        let mut g2 = vec![0f32; n];
        tp.regularise(which, weight, &mut g2).unwrap();
        assert_eq!(g, g2);
        let mut tp2 = tp.clone();
        check_fd(&format!("{which:?}"), &p, &g, 1e-4, 2e-3, |pp| {
            tp2.set_params(pp).unwrap();
            let mut scratch = vec![0f32; n];
            tp2.regularise(which, weight, &mut scratch).unwrap()
        });
    }
    // At 4DGaussians' initialisation the space-time planes are 1: no L1 or time-smoothness.
    let init = TriPlaneConfig::new(4, &[8], PlaneCombine::Product)
        .time(TimeAxis::new(6, 0.0, 1.0))
        .build()
        .unwrap();
    for which in [PlaneRegulariser::TimeL1, PlaneRegulariser::TimeSmoothness] {
        let mut g = vec![0f32; init.param_count()];
        assert_eq!(init.regularise(which, 1.0, &mut g).unwrap(), 0.0);
        assert!(g.iter().all(|&v| v == 0.0));
    }
    // No time axis: the space-time regularisers are 0.
    let tri = TriPlaneConfig::new(2, &[4], PlaneCombine::Product)
        .build()
        .unwrap();
    let mut g = vec![0f32; tri.param_count()];
    assert_eq!(
        tri.regularise(PlaneRegulariser::TimeL1, 1.0, &mut g)
            .unwrap(),
        0.0
    );
    assert!(
        tri.regularise(PlaneRegulariser::SpaceSmoothness, 1.0, &mut g)
            .unwrap()
            > 0.0
    );
    assert!(
        tp.regularise(PlaneRegulariser::TimeL1, 1.0, &mut [0.0; 3])
            .is_err()
    );
}

#[test]
fn f16_hexplane_agrees_with_f32_and_rows_cross_blocks() {
    let cfg = TriPlaneConfig::new(4, &[6, 9], PlaneCombine::Product)
        .time(TimeAxis::new(5, 0.0, 1.0))
        .seed(2);
    let a = cfg.clone().build().unwrap();
    let b = cfg.precision(Precision::F16).build().unwrap();
    let rows = 2500; // more than two encoder blocks
    let x: Vec<f32> = vals(rows * 4, 3, 0.9)
        .iter()
        .enumerate()
        .map(|(i, v)| if i % 4 == 3 { 0.5 + 0.5 * v } else { *v })
        .collect();
    let (ya, ca) = a.forward(&x, rows).unwrap();
    let (yb, _) = b.forward(&x, rows).unwrap();
    for (u, v) in ya.iter().zip(&yb) {
        assert!((u - v).abs() <= 2e-3 * (u.abs() + 1e-3), "{u} vs {v}");
    }
    let c = vals(rows * a.output_width(), 4, 1.0);
    let g = a.backward(&ca, &c, true).unwrap();
    // Row-wise input gradients equal those of a one-row pass.
    for row in [0usize, 1023, 1024, 2499] {
        let (_, c1) = a.forward(&x[row * 4..row * 4 + 4], 1).unwrap();
        let w = a.output_width();
        let g1 = a.backward(&c1, &c[row * w..(row + 1) * w], true).unwrap();
        assert_eq!(
            &g.positions.as_ref().unwrap()[row * 4..row * 4 + 4],
            &g1.positions.unwrap()[..]
        );
    }
    let total = dot(&ya, &c);
    assert!(total.is_finite());
}

#[test]
fn the_observation_network_rejects_a_time_axis() {
    let e = ObservationNet::new(ObservationConfig {
        triplane: TriPlaneConfig::new(2, &[4], PlaneCombine::Product)
            .time(TimeAxis::new(4, 0.0, 1.0)),
        bspline: tiny_nn::BSplineConfig::new(4, 2),
        width: 8,
        hidden_layers: 1,
        output: 3,
        precision: Precision::F32,
        seed: 0,
    })
    .unwrap_err();
    assert!(e.to_string().contains("time axis"), "{e}");
}
