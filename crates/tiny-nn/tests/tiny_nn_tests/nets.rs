//! Composite networks (Φ, D-3DGS) and safetensors weights.

use crate::common;

use common::{check_fd, dot, vals};
use tiny_nn::weights::{load, save};
use tiny_nn::{
    BSplineConfig, DeformConfig, DeformNet, ObservationConfig, ObservationNet, Parameters,
    PlaneCombine, Precision, TriPlaneConfig,
};

fn phi(precision: Precision) -> ObservationNet {
    ObservationNet::new(ObservationConfig {
        triplane: TriPlaneConfig::new(2, &[3, 4], PlaneCombine::Product)
            .bounds([-1.0, -1.0, 0.0], [1.0, 2.0, 1.0]),
        bspline: BSplineConfig::new(5, 3),
        width: 6,
        hidden_layers: 2,
        output: 4,
        precision,
        seed: 21,
    })
    .unwrap()
}

fn inputs(rows: usize) -> (Vec<f32>, Vec<f32>) {
    let p = vals(rows * 3, 30, 0.9)
        .chunks(3)
        .flat_map(|c| [c[0], 0.5 + 1.5 * c[1], 0.5 + 0.5 * c[2]])
        .collect();
    let t = vals(rows, 31, 0.49).iter().map(|v| v + 0.5).collect();
    (p, t)
}

#[test]
fn observation_net_starts_at_zero() {
    let net = phi(Precision::F32);
    let (p, t) = inputs(50);
    let (y, _) = net.forward(&p, &t, 50).unwrap();
    assert!(y.iter().all(|&v| v == 0.0));
}

/// The rows at one shared time, as a training step queries Φ (its B-spline is evaluated once).
fn shared_time(rows: usize) -> Vec<f32> {
    vec![0.37; rows]
}

#[test]
fn observation_net_gradients_match_finite_differences() {
    let (p, t) = inputs(4);
    observation_net_fd(&p, &t);
    observation_net_fd(&p, &shared_time(4));
}

fn observation_net_fd(p: &[f32], t: &[f32]) {
    let mut net = phi(Precision::F32);
    let n = net.mlp.param_count();
    net.mlp.set_params(&vals(n, 40, 0.5)).unwrap();
    let rows = t.len();
    let p = p.to_vec();
    let c = vals(rows * 4, 41, 1.0);
    let (_, cache) = net.forward(&p, t, rows).unwrap();
    let g = net.backward(&cache, &c, true).unwrap();
    let mut n2 = net.clone();
    let tp = net.triplane.params().to_vec_f32();
    check_fd("Φ tri-plane", &tp, &g.triplane, 1e-2, 3e-3, |pp| {
        n2.triplane.set_params(pp).unwrap();
        dot(&n2.forward(&p, t, rows).unwrap().0, &c)
    });
    let mut n2 = net.clone();
    let bp = net.bspline.params().to_vec_f32();
    check_fd("Φ B-spline", &bp, &g.bspline, 1e-2, 3e-3, |pp| {
        n2.bspline.set_params(pp).unwrap();
        dot(&n2.forward(&p, t, rows).unwrap().0, &c)
    });
    let mut n2 = net.clone();
    let mp = net.mlp.params().to_vec_f32();
    check_fd("Φ MLP", &mp, &g.mlp, 1e-3, 5e-3, |pp| {
        n2.mlp.set_params(pp).unwrap();
        dot(&n2.forward(&p, t, rows).unwrap().0, &c)
    });
    check_fd("Φ positions", &p, &g.positions.unwrap(), 1e-3, 5e-3, |pp| {
        dot(&net.forward(pp, t, rows).unwrap().0, &c)
    });
}

#[test]
fn observation_net_f16_agrees_with_f32() {
    let mut a = phi(Precision::F32);
    let mut b = phi(Precision::F16);
    let n = a.mlp.param_count();
    let w = vals(n, 50, 0.5);
    a.mlp.set_params(&w).unwrap();
    b.mlp.set_params(&w).unwrap();
    let rows = 3000;
    let (p, t) = inputs(rows);
    let (ya, _) = a.forward(&p, &t, rows).unwrap();
    let (yb, cb) = b.forward(&p, &t, rows).unwrap();
    let err = ya
        .iter()
        .zip(&yb)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    let scale = ya.iter().map(|v| v.abs()).fold(0.0, f32::max);
    assert!(
        err <= 5e-3 * scale.max(1.0),
        "max error {err} (scale {scale})"
    );
    assert_eq!(cb.saturations(), 0);
}

fn small_deform(precision: Precision) -> DeformNet {
    DeformNet::new(DeformConfig {
        width: 8,
        depth: 4,
        skip_after: Some(2),
        xyz_freqs: 3,
        t_freqs: 2,
        precision,
        seed: 5,
        ..DeformConfig::d3dgs()
    })
    .unwrap()
}

#[test]
fn deform_net_gradients_match_finite_differences() {
    let net = small_deform(Precision::F32);
    let rows = 3;
    let (p, t) = inputs(rows);
    let c = vals(rows * DeformNet::OUTPUT, 60, 1.0);
    let (y, cache) = net.forward(&p, &t, rows).unwrap();
    assert_eq!(y.len(), rows * 10);
    let g = net.backward(&cache, &c, true).unwrap();
    let mut n2 = net.clone();
    let mp = net.mlp.params().to_vec_f32();
    check_fd("D-3DGS MLP", &mp, &g.mlp, 1e-3, 5e-3, |pp| {
        n2.mlp.set_params(pp).unwrap();
        dot(&n2.forward(&p, &t, rows).unwrap().0, &c)
    });
    check_fd(
        "D-3DGS positions",
        &p,
        &g.positions.unwrap(),
        1e-3,
        5e-3,
        |pp| dot(&net.forward(pp, &t, rows).unwrap().0, &c),
    );
    let e = net
        .forward(&[0.0, f32::NAN, 0.0], &[0.5], 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("positions") && e.contains("row 0"), "{e}");
    let e = net
        .forward(&[0.0; 6], &[0.5, f32::INFINITY], 2)
        .unwrap_err()
        .to_string();
    assert!(e.contains("times") && e.contains("row 1"), "{e}");
    let reference = DeformNet::new(DeformConfig::d3dgs()).unwrap();
    assert_eq!(reference.mlp.input_width(), 63 + 13);
    assert_eq!(reference.mlp.layers()[5].input, 256 + 76);
}

fn bits(net: &impl Parameters) -> Vec<Vec<u32>> {
    net.named_params()
        .iter()
        .map(|(_, s)| match s {
            tiny_nn::StoreRef::F32(v) => v.iter().map(|x| x.to_bits()).collect(),
            tiny_nn::StoreRef::F16(v) => v.iter().map(|x| x.to_bits() as u32).collect(),
        })
        .collect()
}

#[test]
fn weights_round_trip_bit_exact_in_both_precisions() {
    let dir = tempfile::tempdir().unwrap();
    for precision in [Precision::F32, Precision::F16] {
        let mut a = phi(precision);
        let n = a.mlp.param_count();
        a.mlp.set_params(&vals(n, 70, 3.0)).unwrap();
        let path = dir.path().join(format!("phi-{precision:?}.safetensors"));
        save(&path, &a).unwrap();
        let mut b = phi(precision);
        assert_ne!(bits(&a), bits(&b));
        load(&path, &mut b).unwrap();
        assert_eq!(bits(&a), bits(&b));
        // f16 stored as F16: two bytes per value plus the header.
        let size = std::fs::metadata(&path).unwrap().len() as usize;
        let values: usize = a.named_params().iter().map(|(_, s)| s.len()).sum();
        let per = if precision == Precision::F16 { 2 } else { 4 };
        assert!(size >= values * per && size < values * per + 1024, "{size}");
    }
}

#[test]
fn weights_errors_name_the_file_and_the_tensor() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.safetensors");
    save(&path, &phi(Precision::F32)).unwrap();
    let e = load(&path, &mut phi(Precision::F16))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("w.safetensors") && e.contains("triplane.planes") && e.contains("dtype"),
        "{e}"
    );
    let e = load(&path, &mut small_deform(Precision::F32))
        .unwrap_err()
        .to_string();
    assert!(e.contains("mlp.params"), "{e}");
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.safetensors");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = load(&cut, &mut phi(Precision::F32))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cut.safetensors"), "{e}");
    let e = load(&dir.path().join("missing"), &mut phi(Precision::F32))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing"), "{e}");
}

#[test]
fn fused_paths_match_the_separate_modules_over_many_blocks() {
    let rows = 2100; // 9 forward blocks of 256 and 3 backward blocks of 1024, the last partial
    let (p, t) = inputs(rows);
    phi_matches_its_modules(&p, &t);
    // One time for all rows, as a training step queries Φ: the B-spline is evaluated once.
    phi_matches_its_modules(&p, &shared_time(rows));
    deform_net_matches_single_rows(&p, &t);
}

/// Φ's fused forward and backward against its encoders, concatenation and decoder run apart.
fn phi_matches_its_modules(p: &[f32], t: &[f32]) {
    let mut net = phi(Precision::F32);
    let n = net.mlp.param_count();
    net.mlp.set_params(&vals(n, 80, 0.5)).unwrap();
    let rows = t.len();
    let d = vals(rows * 4, 81, 1.0);
    let (y, cache) = net.forward(p, t, rows).unwrap();
    let g = net.backward(&cache, &d, true).unwrap();
    // Separate: encoders, concatenation, MLP.
    let (fx, tc) = net.triplane.forward(p, rows).unwrap();
    let (ft, bc) = net.bspline.forward(t).unwrap();
    let (wx, wt) = (net.triplane.output_width(), net.bspline.output_width());
    let input: Vec<f32> = (0..rows)
        .flat_map(|r| {
            fx[r * wx..(r + 1) * wx]
                .iter()
                .chain(&ft[r * wt..(r + 1) * wt])
                .copied()
        })
        .collect();
    let (y2, mc) = net.mlp.forward(&input, rows).unwrap();
    assert_eq!(y, y2);
    let gm = net.mlp.backward(&mc, &d, true).unwrap();
    let gi = gm.input.unwrap();
    let dx: Vec<f32> = gi.chunks(wx + wt).flat_map(|r| r[..wx].to_vec()).collect();
    let dt: Vec<f32> = gi.chunks(wx + wt).flat_map(|r| r[wx..].to_vec()).collect();
    let gt = net.triplane.backward(&tc, &dx, true).unwrap();
    let gb = net.bspline.backward(&bc, &dt, false).unwrap();
    let close = |a: &[f32], b: &[f32]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-5 * (1.0 + y.abs()))
    };
    assert!(close(&g.mlp, &gm.params));
    assert!(close(&g.triplane, &gt.params));
    assert!(close(&g.bspline, &gb.params));
    assert_eq!(g.positions.unwrap(), gt.positions.unwrap());
}

/// The D-3DGS network over many blocks against one row at a time.
fn deform_net_matches_single_rows(p: &[f32], t: &[f32]) {
    let rows = t.len();
    let close = |a: &[f32], b: &[f32]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-5 * (1.0 + y.abs()))
    };
    let dn = small_deform(Precision::F32);
    let (y, cache) = dn.forward(p, t, rows).unwrap();
    let d10 = vals(rows * 10, 82, 1.0);
    let g = dn.backward(&cache, &d10, true).unwrap();
    for r in [0usize, 255, 256, 1023, 1024, 2099] {
        let (y1, c1) = dn.forward(&p[r * 3..r * 3 + 3], &t[r..r + 1], 1).unwrap();
        assert_eq!(&y[r * 10..r * 10 + 10], &y1[..]);
        let g1 = dn.backward(&c1, &d10[r * 10..r * 10 + 10], true).unwrap();
        let gp = g.positions.as_ref().unwrap();
        assert!(close(&gp[r * 3..r * 3 + 3], &g1.positions.unwrap()));
    }
}

#[test]
fn observation_net_f16_saturates_huge_features_without_inf() {
    let mut net = phi(Precision::F16);
    let n = net.triplane.param_count();
    net.triplane.set_params(&vec![1000.0; n]).unwrap(); // product of three planes: 1e9
    let m = net.mlp.param_count();
    net.mlp.set_params(&vals(m, 90, 0.5)).unwrap();
    let rows = 10;
    let (p, t) = inputs(rows);
    let (y, cache) = net.forward(&p, &t, rows).unwrap();
    assert!(y.iter().all(|v| v.is_finite()), "{y:?}");
    // 2 channels × 2 resolutions of product features per row saturate in the stored input.
    assert!(
        cache.saturations() >= (rows * 4) as u64,
        "{}",
        cache.saturations()
    );
    let g = net
        .backward(&cache, &vals(rows * 4, 91, 1.0), true)
        .unwrap();
    assert!(g.mlp.iter().chain(&g.triplane).all(|v| v.is_finite()));
}

/// Parameter gradients are reduced over row blocks in a fixed grouping, so they are bit-identical
/// for any thread count and any scheduling (training is reproducible for a seed).
#[test]
fn observation_net_gradients_are_bit_identical_for_any_thread_count() {
    let mut net = phi(Precision::F32);
    let n = net.mlp.param_count();
    net.mlp.set_params(&vals(n, 42, 0.5)).unwrap();
    // Many rows, so that several blocks (and groups) take part.
    let rows = 20_000;
    let (p, t) = inputs(rows);
    for t in [t, shared_time(rows)] {
        phi_grads_do_not_depend_on_threads(&net, &p, &t);
    }
}

fn phi_grads_do_not_depend_on_threads(net: &ObservationNet, p: &[f32], t: &[f32]) {
    let rows = t.len();
    let c = vals(rows * 4, 43, 1.0);
    let grads_with = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (_, cache) = net.forward(p, t, rows).unwrap();
            let g = net.backward(&cache, &c, true).unwrap();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            (bits(&g.triplane), bits(&g.bspline), bits(&g.mlp))
        })
    };
    let one = grads_with(1);
    for threads in [2, 3] {
        for _ in 0..3 {
            assert!(grads_with(threads) == one, "{threads} threads differ");
        }
    }
}

/// A new weights file gets the usual 0644 (the temporary file's private 0600 does not survive
/// the rename); a replaced one keeps the mode it had.
#[cfg(unix)]
#[test]
fn weights_files_get_0644_and_replaced_ones_keep_their_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    let fresh = dir.path().join("fresh.safetensors");
    save(&fresh, &phi(Precision::F32)).unwrap();
    assert_eq!(mode(&fresh), 0o644);
    std::fs::set_permissions(&fresh, std::fs::Permissions::from_mode(0o600)).unwrap();
    save(&fresh, &phi(Precision::F32)).unwrap();
    assert_eq!(mode(&fresh), 0o600);
}
