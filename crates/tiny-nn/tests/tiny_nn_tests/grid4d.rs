//! The Grid4D deformation field: the f32 forward against its f64 reference (inside and outside
//! the box, times outside [0, 1]), every parameter gradient against f64 central differences of
//! the reference, the smoothness regulariser's value and gradients, the rigid warp, zero heads,
//! Grid4D's D-NeRF layout, weights round trip, bad inputs and configurations.

use crate::common;

use common::vals;
use tiny_nn::weights::{load, save};
use tiny_nn::{
    Grid4dConfig, Grid4dHead, Grid4dNet, Grid4dSmoothness, HashGridConfig, Interpolation, Outside,
    Parameters, Precision,
};

const BOUND: f32 = 1.6;

/// Small grids with dense and hashed levels (tables of 2^5 and 2^6 entries collide), every head,
/// tables and heads at O(1) values so every part of the field shows in the output.
fn small(depth: usize, directional: bool) -> Grid4dNet {
    let grid = |levels, log2, base: f32, finest: &[f32], seed| {
        HashGridConfig::new(3, levels, 2, log2, base, finest[0])
            .resolutions(&[base; 3], finest)
            .bounds(&[-BOUND; 3], &[BOUND; 3])
            .interpolation(Interpolation::Smoothstep)
            .outside(Outside::Zero)
            .seed(seed)
    };
    let mut net = Grid4dNet::new(Grid4dConfig {
        spatial: grid(3, 6, 2.0, &[9.0; 3], 3),
        temporal: grid(3, 5, 2.0, &[6.0, 6.0, 4.0], 4),
        time_span: 0.9,
        width: 6,
        depth,
        directional,
        heads: vec![
            Grid4dHead::Position,
            Grid4dHead::Rotation,
            Grid4dHead::Scale,
            Grid4dHead::Opacity,
            Grid4dHead::Colour,
        ],
        zero_heads: false,
        smoothness: Grid4dSmoothness {
            spatial_weight: 0.5,
            temporal_weight: 0.25,
            sample_ratio: 0.5,
            spatial_range: [0.1, 0.2, 0.15],
            temporal_range: [0.1, 0.1, 0.2, 0.05],
        },
        precision: Precision::F32,
        seed: 11,
    })
    .unwrap();
    let mut k = 0;
    for (_, mut buf) in net.named_params_mut() {
        k += 1;
        let v = vals(buf.len(), 50 + k, 0.8);
        buf.write_from(&v);
    }
    net
}

/// Rows inside the box with times in [0, 1].
fn inputs(rows: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let p = vals(rows * 3, seed, 1.2);
    let t = vals(rows, seed + 1, 0.5).iter().map(|v| 0.5 + v).collect();
    (p, t)
}

fn params64(net: &Grid4dNet) -> Vec<Vec<f64>> {
    net.named_params()
        .iter()
        .map(|(_, p)| p.to_vec_f32().iter().map(|&v| v as f64).collect())
        .collect()
}

fn reference(net: &Grid4dNet, params: &[Vec<f64>], p: &[f32], t: &[f32]) -> Vec<f64> {
    p.chunks(3)
        .zip(t)
        .flat_map(|(x, &t)| {
            net.reference_forward(params, [x[0] as f64, x[1] as f64, x[2] as f64], t as f64)
        })
        .collect()
}

fn assert_close(what: &str, got: &[f32], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (&g, &w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g as f64 - w).abs() <= tol * (1.0 + w.abs()),
            "{what} {i}: {g} vs reference {w}"
        );
    }
}

#[test]
fn forward_matches_the_f64_reference_inside_outside_and_beyond_the_sequence() {
    for (depth, directional) in [(0, true), (2, true), (1, false)] {
        let net = small(depth, directional);
        let params = params64(&net);
        let (mut p, mut t) = inputs(9, 7);
        // Outside the box on one axis (zero spatial and temporal features), far outside, and
        // times before 0 and after 1 (t' beyond the time axis: zero temporal features).
        p.extend([
            1.7, 1.7, 1.7, -5.0, 9.0, 0.0, 0.3, -0.2, 0.1, 0.3, -0.2, 0.1,
        ]);
        t.extend([0.5, 0.5, -0.4, 1.6]);
        let rows = t.len();
        let (y, _) = net.forward(&p, &t, rows).unwrap();
        assert_eq!(y.len(), rows * net.output_width());
        assert_eq!(net.output_width(), 14);
        assert_close("output", &y, &reference(&net, &params, &p, &t), 2e-5);
        // Rows outside the box on an axis of every grid see the field of zero features: the
        // two such rows agree but for the position (the warp moves each point).
        let w = net.output_width();
        assert_eq!(y[9 * w + 3..10 * w], y[10 * w + 3..11 * w]);
        // Times outside [0, 1] are accepted and differ from the sequence's ends only through
        // the time axis: beyond it, t = -0.4 and t = 1.6 see the same (zero) temporal features.
        assert_eq!(y[11 * w + 3..12 * w], y[12 * w + 3..13 * w]);
    }
}

#[test]
fn every_parameter_gradient_matches_f64_finite_differences() {
    for (depth, directional) in [(0, true), (1, false)] {
        let net = small(depth, directional);
        let (mut p, mut t) = inputs(7, 21);
        p.extend([1.7, 0.1, 0.2]);
        t.push(1.3);
        let rows = t.len();
        let c = vals(rows * net.output_width(), 33, 1.0);
        let (_, cache) = net.forward(&p, &t, rows).unwrap();
        let grads = net.backward(&cache, &c).unwrap().into_buffers();
        let params = params64(&net);
        let names: Vec<String> = net.named_params().into_iter().map(|(n, _)| n).collect();
        assert_eq!(grads.len(), params.len());
        let loss = |pp: &[Vec<f64>]| -> f64 {
            reference(&net, pp, &p, &t)
                .iter()
                .zip(&c)
                .map(|(y, &c)| y * c as f64)
                .sum()
        };
        for (b, name) in names.iter().enumerate() {
            let mut pp = params.clone();
            let mut nonzero = false;
            for i in 0..params[b].len() {
                let h = 1e-6;
                pp[b][i] = params[b][i] + h;
                let lp = loss(&pp);
                pp[b][i] = params[b][i] - h;
                let lm = loss(&pp);
                pp[b][i] = params[b][i];
                let fd = (lp - lm) / (2.0 * h);
                let g = grads[b][i] as f64;
                assert!(
                    (g - fd).abs() <= 2e-4 * (1.0 + fd.abs()),
                    "depth {depth} {name} {i}: analytic {g} vs finite difference {fd}"
                );
                nonzero |= fd.abs() > 1e-3;
            }
            assert!(nonzero, "{name}: no gradient (the test could not fail)");
        }
    }
}

/// The smoothness terms from the reference encoders, in f64.
fn reference_smoothness(
    net: &Grid4dNet,
    params: &[Vec<f64>],
    xyzt: &[f32],
    rows: (&[usize], &[f32], &[usize], &[f32]),
) -> f64 {
    let sm = &net.config().smoothness;
    let (sr, sj, tr, tj) = rows;
    let at = |r: usize| -> [f64; 4] { std::array::from_fn(|a| xyzt[r * 4 + a] as f64) };
    let mut spatial = 0.0;
    for (&r, j) in sr.iter().zip(sj.chunks(3)) {
        let x = at(r);
        let moved: Vec<f64> = (0..3)
            .map(|a| x[a] + (j[a] * sm.spatial_range[a]) as f64)
            .collect();
        let f0 = net.spatial.reference_encode(&params[0], &x[..3]);
        let f1 = net.spatial.reference_encode(&params[0], &moved);
        spatial += f0
            .iter()
            .zip(&f1)
            .map(|(a, b)| (b - a).powi(2))
            .sum::<f64>();
    }
    let axes = [[0, 1, 3], [1, 2, 3], [0, 2, 3]];
    let mut temporal = 0.0;
    for (&r, j) in tr.iter().zip(tj.chunks(4)) {
        let x = at(r);
        let moved: [f64; 4] = std::array::from_fn(|a| x[a] + (j[a] * sm.temporal_range[a]) as f64);
        for (g, ax) in axes.iter().enumerate() {
            let f0 = net.temporal[g].reference_encode(&params[1 + g], &ax.map(|a| x[a]));
            let f1 = net.temporal[g].reference_encode(&params[1 + g], &ax.map(|a| moved[a]));
            temporal += f0
                .iter()
                .zip(&f1)
                .map(|(a, b)| (b - a).powi(2))
                .sum::<f64>();
        }
    }
    sm.spatial_weight as f64 * spatial / sr.len() as f64
        + sm.temporal_weight as f64 * temporal / tr.len() as f64
}

#[test]
fn smoothness_value_and_table_gradients_match_the_f64_reference() {
    let net = small(0, true);
    let (p, t) = inputs(8, 40);
    let rows = t.len();
    let (_, cache) = net.forward(&p, &t, rows).unwrap();
    let c = vals(rows * net.output_width(), 41, 1.0);
    let g0 = net.backward(&cache, &c).unwrap();
    let (sr, tr) = (vec![1usize, 4, 6, 7], vec![0usize, 2, 5]);
    let sj = vals(sr.len() * 3, 42, 1.0);
    let tj = vals(tr.len() * 4, 43, 1.0);
    let mut g = g0.clone();
    let value = net.smoothness(&cache, &sr, &sj, &tr, &tj, &mut g).unwrap();
    let params = params64(&net);
    let xyzt = cache.encoder_inputs().to_vec();
    let want = reference_smoothness(&net, &params, &xyzt, (&sr, &sj, &tr, &tj));
    assert!(want > 1e-3, "the moves change the features");
    assert!((value - want).abs() <= 1e-4 * want, "{value} vs {want}");
    // The regulariser's gradient alone is what smoothness added; MLPs untouched.
    assert_eq!(g.attention, g0.attention);
    assert_eq!(g.heads, g0.heads);
    let added: Vec<Vec<f32>> = [&g.spatial, &g.temporal[0], &g.temporal[1], &g.temporal[2]]
        .iter()
        .zip([
            &g0.spatial,
            &g0.temporal[0],
            &g0.temporal[1],
            &g0.temporal[2],
        ])
        .map(|(a, b)| a.iter().zip(b.iter()).map(|(x, y)| x - y).collect())
        .collect();
    for (b, grad) in added.iter().enumerate() {
        let mut pp = params.clone();
        let mut nonzero = false;
        for i in 0..pp[b].len() {
            let h = 1e-6;
            pp[b][i] = params[b][i] + h;
            let lp = reference_smoothness(&net, &pp, &xyzt, (&sr, &sj, &tr, &tj));
            pp[b][i] = params[b][i] - h;
            let lm = reference_smoothness(&net, &pp, &xyzt, (&sr, &sj, &tr, &tj));
            pp[b][i] = params[b][i];
            let fd = (lp - lm) / (2.0 * h);
            assert!(
                (grad[i] as f64 - fd).abs() <= 1e-3 * (1.0 + fd.abs()),
                "table {b} entry {i}: analytic {} vs finite difference {fd}",
                grad[i]
            );
            nonzero |= fd.abs() > 1e-4;
        }
        assert!(nonzero, "table {b}: no gradient");
    }
    // Weight 0 or no rows add nothing; rows past the cache are errors.
    let mut gz = g0.clone();
    assert_eq!(
        net.smoothness(&cache, &[], &[], &[], &[], &mut gz).unwrap(),
        0.0
    );
    assert_eq!(gz, g0);
    assert!(
        net.smoothness(&cache, &[rows], &[0.0; 3], &[], &[], &mut gz)
            .is_err()
    );
    assert!(
        net.smoothness(&cache, &[0], &[0.0; 2], &[], &[], &mut gz)
            .is_err()
    );
    assert_eq!(Grid4dSmoothness::dnerf().samples(10_000), 1_000);
    assert_eq!(Grid4dSmoothness::dnerf().samples(3), 1);
    assert_eq!(Grid4dSmoothness::dnerf().samples(0), 0);
}

#[test]
fn the_warp_is_a_rigid_motion_and_zero_heads_start_at_zero() {
    let mut net = small(0, true);
    let w = net.output_width();
    // Position head: bias only, q = (1, 0, 0, 0) + (0, 0, 0, 1) (a 90° turn about z, after
    // normalisation), τ = (0.1, 0.2, 0.3).
    let lw = 7;
    let width = net.config().width;
    let mut head = vec![0f32; width * lw + lw];
    head[width * lw..].copy_from_slice(&[0.0, 0.0, 0.0, 1.0, 0.1, 0.2, 0.3]);
    net.heads[0].set_params(&head).unwrap();
    let p = [0.5f32, -0.25, 0.75, 1.0, 2.0, -1.0];
    let (y, _) = net.forward(&p, &[0.3, 0.8], 2).unwrap();
    for (r, x) in p.chunks(3).enumerate() {
        // R_z(90°) x = (-y, x, z).
        let moved = [-x[1] + 0.1, x[0] + 0.2, x[2] + 0.3];
        for a in 0..3 {
            assert!(
                (y[r * w + a] - (moved[a] - x[a])).abs() < 1e-6,
                "row {r} axis {a}"
            );
        }
    }
    // A zero quaternion (bias -1 on the real part) stays finite.
    head[width * lw..width * lw + 4].copy_from_slice(&[-1.0, 0.0, 0.0, 0.0]);
    net.heads[0].set_params(&head).unwrap();
    let (y, cache) = net.forward(&p, &[0.3, 0.8], 2).unwrap();
    assert!(y.iter().all(|v| v.is_finite()));
    let g = net.backward(&cache, &vec![1.0; 2 * w]).unwrap();
    assert!(g.heads[0].iter().all(|v| v.is_finite()));

    let mut config = net.config().clone();
    config.zero_heads = true;
    let zero = Grid4dNet::new(config).unwrap();
    let (y, _) = zero.forward(&p, &[0.3, 0.8], 2).unwrap();
    assert!(y.iter().all(|&v| v == 0.0), "{y:?}");
}

#[test]
fn dnerf_layout_weights_round_trip_and_bad_input_are_errors() {
    let c = Grid4dConfig::dnerf(1.6, 0);
    assert_eq!(
        (c.spatial.levels, c.spatial.features, c.spatial.log2_table),
        (16, 2, 19)
    );
    assert_eq!(c.spatial.finest_resolution, [2048.0; 3]);
    assert_eq!((c.temporal.levels, c.temporal.log2_table), (32, 19));
    assert_eq!(c.temporal.finest_resolution, [32.0, 32.0, 16.0]);
    assert_eq!((c.width, c.depth, c.directional), (256, 0, true));
    assert_eq!(c.output_width(), 10);
    assert_eq!(c.smoothness, Grid4dSmoothness::dnerf());

    let net = small(1, true);
    let names: Vec<String> = net.named_params().into_iter().map(|(n, _)| n).collect();
    assert_eq!(
        names,
        [
            "grid_xyz",
            "grid_xyt",
            "grid_yzt",
            "grid_xzt",
            "attention",
            "temporal",
            "trunk",
            "head_position",
            "head_rotation",
            "head_scale",
            "head_opacity",
            "head_colour"
        ]
    );
    let dir = std::env::temp_dir().join(format!("grid4d-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("w.safetensors");
    save(&path, &net).unwrap();
    let mut config = net.config().clone();
    config.seed = 99;
    let mut other = Grid4dNet::new(config).unwrap();
    let (p, t) = inputs(5, 3);
    assert_ne!(
        net.forward(&p, &t, 5).unwrap().0,
        other.forward(&p, &t, 5).unwrap().0
    );
    load(&path, &mut other).unwrap();
    assert_eq!(
        net.forward(&p, &t, 5).unwrap().0,
        other.forward(&p, &t, 5).unwrap().0
    );
    std::fs::remove_dir_all(&dir).unwrap();

    assert!(net.forward(&p[..6], &t, 5).is_err());
    assert!(net.forward(&p, &[0.5, f32::NAN, 0.5, 0.5, 0.5], 5).is_err());
    let mut bad_p = p.clone();
    bad_p[4] = f32::INFINITY;
    assert!(net.forward(&bad_p, &t, 5).is_err());
    let (_, cache) = net.forward(&p, &t, 5).unwrap();
    assert!(net.backward(&cache, &[0.0; 3]).is_err());

    let base = net.config().clone();
    let mut configs = Vec::new();
    let mut c = base.clone();
    c.width = 0;
    configs.push(c);
    let mut c = base.clone();
    c.heads.clear();
    configs.push(c);
    let mut c = base.clone();
    c.heads.push(Grid4dHead::Scale);
    configs.push(c);
    let mut c = base.clone();
    c.time_span = 0.0;
    configs.push(c);
    let mut c = base.clone();
    c.spatial = HashGridConfig::new(2, 2, 2, 4, 2.0, 4.0);
    configs.push(c);
    let mut c = base.clone();
    c.smoothness.sample_ratio = 0.0;
    configs.push(c);
    let mut c = base;
    c.smoothness.spatial_weight = f32::NAN;
    configs.push(c);
    for c in configs {
        assert!(Grid4dNet::new(c).is_err());
    }
}
