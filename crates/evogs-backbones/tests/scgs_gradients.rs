//! Finite-difference checks of SC-GS's backbone: the skinning's gradient to the control-point
//! network's outputs, positions, log radii and weight logits (f64 central differences with the
//! neighbours held, as the gradient defines them), and the whole backbone, rows and ARAP loss,
//! into every parameter buffer; and the hard cases (a Gaussian far from every control point,
//! coincident control points, a radius going to zero, one control point, a degenerate local
//! rotation) stay finite.

mod common;

use common::Lcg;
use evogs_backbones::scgs::knn::{self, Neighbours};
use evogs_backbones::scgs::skinning::{
    Controls, LOCAL, NODE_OUTPUT, ROW, SkinGrads, reference, skin_backward, skin_into,
};
use evogs_backbones::{Backbone, EvolutionOn, ScgsBackbone, ScgsSettings};
use proptest::prelude::*;
use splat_core::Gaussians;
use tiny_nn::StoreMut;

/// Control points, their outputs and Gaussians for a skinning check.
struct Scene {
    positions: Vec<[f32; 3]>,
    log_radii: Vec<f32>,
    weight_logits: Vec<f32>,
    nodes: Vec<f32>,
    means: Vec<[f32; 3]>,
    /// dL/d(rows) of the linear test loss `L = Σ r · rows`.
    r: Vec<f32>,
}

impl Scene {
    fn new(m: usize, n: usize, seed: u64) -> Self {
        let mut rng = Lcg(seed);
        let mut v = |s: f32| rng.next() * s;
        let positions = (0..m).map(|_| [v(0.8), v(0.8), v(0.8)]).collect();
        let log_radii = (0..m).map(|_| -0.7 + v(0.3)).collect();
        let weight_logits = (0..m).map(|_| v(1.0)).collect();
        let nodes = (0..m * NODE_OUTPUT).map(|_| v(0.3)).collect();
        let means = (0..n).map(|_| [v(1.0), v(1.0), v(1.0)]).collect();
        let r = (0..n * ROW).map(|_| v(1.0)).collect();
        Self {
            positions,
            log_radii,
            weight_logits,
            nodes,
            means,
            r,
        }
    }

    fn controls(&self) -> Controls<'_> {
        Controls {
            positions: &self.positions,
            log_radii: &self.log_radii,
            weight_logits: &self.weight_logits,
        }
    }

    fn loss(&self, nb: &Neighbours) -> f64 {
        let mut rows = Vec::new();
        skin_into(&self.means, nb, self.controls(), &self.nodes, &mut rows);
        rows.iter()
            .zip(&self.r)
            .map(|(a, b)| f64::from(*a) * f64::from(*b))
            .sum()
    }

    fn grads(&self, nb: &Neighbours) -> SkinGrads {
        skin_backward(&self.means, nb, self.controls(), &self.nodes, &self.r)
    }
}

/// `|fd − g| ≤ tol · max(|g|, floor)`.
fn close(fd: f64, g: f64, what: &str) {
    assert!(
        (fd - g).abs() <= 2e-2 * g.abs().max(2e-2),
        "{what}: finite difference {fd} vs gradient {g}"
    );
}

/// Central difference of the scene's loss in one value chosen by `pick`.
fn fd(scene: &Scene, nb: &Neighbours, pick: impl Fn(&mut Scene) -> &mut f32) -> f64 {
    let h = 1e-3f32;
    let mut plus = clone(scene);
    let mut minus = clone(scene);
    let x = *pick(&mut plus);
    *pick(&mut plus) = x + h;
    *pick(&mut minus) = x - h;
    let step = f64::from(x + h) - f64::from(x - h);
    (plus.loss(nb) - minus.loss(nb)) / step
}

fn clone(s: &Scene) -> Scene {
    Scene {
        positions: s.positions.clone(),
        log_radii: s.log_radii.clone(),
        weight_logits: s.weight_logits.clone(),
        nodes: s.nodes.clone(),
        means: s.means.clone(),
        r: s.r.clone(),
    }
}

/// The skinning's gradient to every kind of input matches central differences.
#[test]
fn skinning_gradient_matches_finite_differences() {
    let scene = Scene::new(6, 12, 11);
    let nb = knn::nearest(&scene.positions, &scene.means, 3).unwrap();
    let g = scene.grads(&nb);
    for idx in (0..6 * NODE_OUTPUT).step_by(5) {
        close(
            fd(&scene, &nb, |s| &mut s.nodes[idx]),
            f64::from(g.nodes[idx]),
            &format!("node output {idx}"),
        );
    }
    for idx in 0..18 {
        close(
            fd(&scene, &nb, |s| &mut s.positions[idx / 3][idx % 3]),
            f64::from(g.positions[idx]),
            &format!("position {idx}"),
        );
    }
    for c in 0..6 {
        close(
            fd(&scene, &nb, |s| &mut s.log_radii[c]),
            f64::from(g.log_radii[c]),
            &format!("log radius {c}"),
        );
        close(
            fd(&scene, &nb, |s| &mut s.weight_logits[c]),
            f64::from(g.weight_logits[c]),
            &format!("weight logit {c}"),
        );
    }
    assert!(g.log_radii.iter().any(|&v| v.abs() > 1e-3));
}

/// Zero motion: zero network outputs move nothing (the rows are zero whatever the weights).
#[test]
fn zero_outputs_are_zero_motion() {
    let mut scene = Scene::new(5, 9, 3);
    scene.nodes.fill(0.0);
    let nb = knn::nearest(&scene.positions, &scene.means, 3).unwrap();
    let mut rows = Vec::new();
    skin_into(&scene.means, &nb, scene.controls(), &scene.nodes, &mut rows);
    assert!(rows.iter().all(|v| v.abs() < 1e-6), "{rows:?}");
}

/// The hard cases give finite rows and gradients: a Gaussian far from every control point (an
/// even blend of ε weights), coincident control points, radii that underflow to zero or
/// overflow, one control point for K = 3, a local rotation of zero norm.
#[test]
fn hard_cases_stay_finite() {
    let finite = |scene: &Scene, k: usize| {
        let nb = knn::nearest(&scene.positions, &scene.means, k).unwrap();
        let mut rows = Vec::new();
        skin_into(&scene.means, &nb, scene.controls(), &scene.nodes, &mut rows);
        let g = scene.grads(&nb);
        assert!(rows.iter().all(|v| v.is_finite()), "rows {rows:?}");
        for (name, v) in [
            ("nodes", &g.nodes),
            ("positions", &g.positions),
            ("log radii", &g.log_radii),
            ("weight logits", &g.weight_logits),
        ] {
            assert!(v.iter().all(|x| x.is_finite()), "{name} {v:?}");
        }
        rows
    };
    // Far away: the translation rows blend the control points' targets evenly.
    let mut far = Scene::new(4, 1, 5);
    far.means[0] = [1e4, -1e4, 1e4];
    far.nodes.fill(0.0);
    let rows = finite(&far, 3);
    assert!(rows.iter().all(|v| v.is_finite()));
    // Coincident control points, and a Gaussian sitting on them.
    let mut same = Scene::new(4, 6, 7);
    same.positions = vec![[0.1, 0.2, 0.3]; 4];
    same.means[0] = [0.1, 0.2, 0.3];
    finite(&same, 3);
    // Radii underflowing to zero and overflowing.
    let mut tiny = Scene::new(5, 8, 9);
    tiny.log_radii = vec![-1e3, -50.0, 60.0, 1e3, 0.0];
    finite(&tiny, 3);
    // One control point, K = 3: every Gaussian follows it.
    let one = Scene::new(1, 7, 13);
    let rows = finite(&one, 3);
    assert_eq!(rows.len(), 7 * ROW);
    // A local quaternion of zero norm is no rotation.
    let mut flat = Scene::new(3, 4, 17);
    for c in 0..3 {
        let l = &mut flat.nodes[c * NODE_OUTPUT..(c + 1) * NODE_OUTPUT][LOCAL];
        l.copy_from_slice(&[-1.0, 0.0, 0.0, 0.0]);
    }
    finite(&flat, 2);
}

/// `a` within `tol · max(max |b|, 1)` of `b`, entry by entry.
fn near(a: &[f32], b: &[f32], tol: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let scale = b.iter().fold(1f64, |m, &v| m.max(f64::from(v).abs()));
    for (i, (&x, &y)) in a.iter().zip(b).enumerate() {
        assert!(
            (f64::from(x) - f64::from(y)).abs() <= tol * scale,
            "{what}[{i}]: {x} against the reference's {y} (scale {scale})"
        );
    }
}

/// The prepared skinning (per-control-point radius, weight, rotation matrix; the rotation's
/// gradient from per-point sums) against its plain per-pair twin: the rows and every gradient
/// agree to f32 rounding. Both sum in f64 and narrow once, so 1e-5 of the largest value bounds
/// the reordering of the sums with room to spare; a wrong term (a transposed rotation, a lost
/// position term) is off by the size of the value itself.
fn matches_reference(scene: &Scene, k: usize) {
    let nb = knn::nearest(&scene.positions, &scene.means, k).unwrap();
    let (mut fast, mut plain) = (Vec::new(), Vec::new());
    skin_into(&scene.means, &nb, scene.controls(), &scene.nodes, &mut fast);
    reference::skin_into(
        &scene.means,
        &nb,
        scene.controls(),
        &scene.nodes,
        &mut plain,
    );
    near(&fast, &plain, 1e-5, "rows");
    let g = scene.grads(&nb);
    let r = reference::skin_backward(&scene.means, &nb, scene.controls(), &scene.nodes, &scene.r);
    near(&g.nodes, &r.nodes, 1e-5, "node outputs");
    near(&g.positions, &r.positions, 1e-5, "positions");
    near(&g.log_radii, &r.log_radii, 1e-5, "log radii");
    near(&g.weight_logits, &r.weight_logits, 1e-5, "weight logits");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Random scenes, from one control point to more than K, with Gaussians over more than
    /// one task of rows and local rotations from small to large.
    #[test]
    fn prepared_skinning_matches_the_plain_reference(
        seed in 0u64..1_000_000,
        m in 1usize..40,
        n in 1usize..2600,
        k in 1usize..6,
        spread in 0.01f32..3.0,
    ) {
        let mut scene = Scene::new(m, n, seed);
        for v in &mut scene.nodes {
            *v *= spread;
        }
        matches_reference(&scene, k);
    }
}

/// The hard cases of `hard_cases_stay_finite` give the reference's values too.
#[test]
fn prepared_skinning_matches_the_reference_in_hard_cases() {
    let mut far = Scene::new(4, 3, 5);
    far.means[0] = [1e4, -1e4, 1e4];
    matches_reference(&far, 3);
    let mut same = Scene::new(4, 6, 7);
    same.positions = vec![[0.1, 0.2, 0.3]; 4];
    same.means[0] = [0.1, 0.2, 0.3];
    matches_reference(&same, 3);
    let mut tiny = Scene::new(5, 8, 9);
    tiny.log_radii = vec![-1e3, -50.0, 60.0, 1e3, 0.0];
    matches_reference(&tiny, 3);
    matches_reference(&Scene::new(1, 7, 13), 3);
    let mut flat = Scene::new(3, 4, 17);
    for c in 0..2 {
        let l = &mut flat.nodes[c * NODE_OUTPUT..(c + 1) * NODE_OUTPUT][LOCAL];
        l.copy_from_slice(&[-1.0, 0.0, 0.0, 0.0]);
    }
    matches_reference(&flat, 2);
}

fn gaussians(n: usize, seed: u64) -> Gaussians {
    let mut rng = Lcg(seed);
    let mut g = Gaussians::with_degree(0);
    for _ in 0..n {
        g.means.push([rng.next(), rng.next(), rng.next()]);
        g.log_scales.push([-2.0; 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(0.0);
        g.sh.extend([0.1, 0.2, 0.3]);
    }
    g
}

/// The backbone's loss `Σ r · rows + λ ARAP` at its current parameters.
fn backbone_loss(b: &mut ScgsBackbone, g: &Gaussians, time: f32, r: &[f32]) -> f64 {
    let rows = b.forward(g.view(), time, true).unwrap();
    b.backward(r).unwrap();
    let linear: f64 = rows
        .iter()
        .zip(r)
        .map(|(a, b)| f64::from(*a) * f64::from(*b))
        .sum();
    linear + b.loss_terms()
}

/// Adds `scale` times the generator's numbers to every network buffer of `b` (those over 100
/// values: the control points' own buffers are left), so that its heads are not zero.
fn shake_network(b: &mut ScgsBackbone, rng: &mut Lcg, scale: f32) {
    for (_, p) in b.params_mut() {
        if let StoreMut::F32(v) = p
            && v.len() > 100
        {
            for x in v.iter_mut() {
                *x += scale * rng.next();
            }
        }
    }
}

/// The whole backbone (network on the control points, skinning, ARAP) against central
/// differences in a sample of every parameter buffer, control positions learning.
#[test]
fn backbone_gradient_matches_finite_differences() {
    let settings = ScgsSettings {
        control_points: 7,
        neighbours: 3,
        width: 12,
        depth: 2,
        // Low frequencies: central differences need an input smooth at the step's scale.
        xyz_freqs: 2,
        t_freqs: 2,
        arap_weight: 0.5,
        position_lr_scale: 1.0,
        follow_densify: false,
        placement: evogs_backbones::Placement::Canonical,
        evolution_on: EvolutionOn::Gaussians,
    };
    let g = gaussians(20, 21);
    let mut b = ScgsBackbone::new(&settings, 1.0, 4).unwrap();
    b.initialise(g.view()).unwrap();
    // Non-zero heads, so that every buffer has a gradient.
    let mut rng = Lcg(99);
    shake_network(&mut b, &mut rng, 0.3);
    let time = 0.4;
    let r: Vec<f32> = (0..20 * ROW).map(|_| rng.next()).collect();
    b.forward(g.view(), time, true).unwrap();
    let grads = b.backward(&r).unwrap();
    assert!(b.loss_terms() > 0.0, "the ARAP term is on");
    let names: Vec<String> = b.params().into_iter().map(|(n, _)| n).collect();
    assert_eq!(grads.len(), names.len());
    for (buffer, name) in names.iter().enumerate() {
        let len = grads[buffer].len();
        let picks: Vec<usize> = (0..len).step_by((len / 9).max(1)).collect();
        for &idx in &picks {
            let h = 2e-3f32;
            let at = |b: &mut ScgsBackbone, delta: f32| {
                let mut params = b.params_mut();
                let StoreMut::F32(v) = &mut params[buffer].1 else {
                    panic!("f32 buffers")
                };
                v[idx] += delta;
            };
            at(&mut b, h);
            let plus = backbone_loss(&mut b, &g, time, &r);
            at(&mut b, -2.0 * h);
            let minus = backbone_loss(&mut b, &g, time, &r);
            at(&mut b, h);
            let fd = (plus - minus) / (2.0 * f64::from(h));
            let grad = f64::from(grads[buffer][idx]);
            assert!(
                (fd - grad).abs() <= 3e-2 * grad.abs().max(3e-2),
                "{name}[{idx}]: finite difference {fd} vs gradient {grad}"
            );
        }
    }
}

/// Control points start on the run's Gaussians, and a saved backbone loads bit for bit.
#[test]
fn control_points_start_on_the_gaussians_and_round_trip() {
    let settings = ScgsSettings {
        control_points: 6,
        width: 8,
        depth: 2,
        ..ScgsSettings::default()
    };
    let g = gaussians(30, 5);
    let mut b = ScgsBackbone::new(&settings, 1.0, 2).unwrap();
    b.initialise(g.view()).unwrap();
    for p in b.control_positions() {
        assert!(g.means.contains(p), "{p:?}");
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("deform.safetensors");
    b.save(&path).unwrap();
    let mut c = ScgsBackbone::new(&settings, 1.0, 99).unwrap();
    c.load(&path).unwrap();
    assert_eq!(c.control_positions(), b.control_positions());
    let rows_b = b.forward(g.view(), 0.3, false).unwrap();
    let rows_c = c.forward(g.view(), 0.3, false).unwrap();
    assert_eq!(rows_b, rows_c);
    // Densification changed the Gaussians: without `follow_densify` nothing moves; with it the
    // points move onto the new Gaussians, each keeping the radius of the old point nearest to it.
    let moved = gaussians(40, 77);
    let before = b.control_positions().to_vec();
    b.gaussians_changed(moved.view()).unwrap();
    assert_eq!(b.control_positions(), before);
    let follows = ScgsSettings {
        follow_densify: true,
        placement: evogs_backbones::Placement::Canonical,
        ..settings
    };
    let mut f = ScgsBackbone::new(&follows, 1.0, 2).unwrap();
    f.initialise(g.view()).unwrap();
    let mut params = f.params_mut();
    let StoreMut::F32(radii) = &mut params[2].1 else {
        panic!("f32 radii")
    };
    for (k, r) in radii.iter_mut().enumerate() {
        *r = -2.0 - k as f32;
    }
    drop(params);
    let old = f.control_positions().to_vec();
    f.gaussians_changed(moved.view()).unwrap();
    let radii = f.control_radii();
    for (p, r) in f.control_positions().iter().zip(radii) {
        assert!(moved.means.contains(p), "{p:?}");
        let nearest = (0..old.len())
            .min_by(|&a, &b| {
                let d = |q: &[f32; 3]| (0..3).map(|c| (q[c] - p[c]).powi(2)).sum::<f32>();
                d(&old[a]).total_cmp(&d(&old[b]))
            })
            .unwrap();
        assert_eq!(r, (-2.0 - nearest as f32).exp());
    }
}

/// `--control-placement trajectories`: after a densification the control points are the
/// Gaussians that farthest-point sampling picks from their trajectories (each one's position
/// under the old control points at 16 times in `[0, 1]`, recomputed here from the backbone's
/// own forward), which with a moving network is another set than the canonical positions give.
#[test]
fn trajectory_placement_spreads_the_points_over_the_gaussians_paths() {
    use evogs_backbones::Placement;
    use evogs_backbones::scgs::{TRAJECTORY_TIMES, fps};
    let settings = ScgsSettings {
        control_points: 6,
        width: 12,
        depth: 2,
        xyz_freqs: 2,
        t_freqs: 2,
        follow_densify: true,
        placement: Placement::Trajectories,
        ..ScgsSettings::default()
    };
    // Without following, the points are placed once, before anything moves: refused.
    let once = ScgsSettings {
        follow_densify: false,
        ..settings
    };
    let refused = ScgsBackbone::new(&once, 1.0, 0).err().unwrap().to_string();
    assert!(refused.contains("scgs.placement"), "{refused}");
    let g = gaussians(30, 5);
    let moved = gaussians(50, 78);
    let seed = 3;
    let mut b = ScgsBackbone::new(&settings, 1.0, seed).unwrap();
    b.initialise(g.view()).unwrap();
    // Non-zero heads: the network moves the control points, differently over time.
    shake_network(&mut b, &mut Lcg(7), 0.5);
    let mut paths = vec![[0f32; 3 * TRAJECTORY_TIMES]; moved.means.len()];
    for j in 0..TRAJECTORY_TIMES {
        let t = j as f32 / (TRAJECTORY_TIMES - 1) as f32;
        let rows = b.forward(moved.view(), t, false).unwrap();
        for ((path, row), x) in paths
            .iter_mut()
            .zip(rows.chunks_exact(ROW))
            .zip(&moved.means)
        {
            for c in 0..3 {
                path[3 * j + c] = x[c] + row[c];
            }
        }
    }
    let expected: Vec<[f32; 3]> = fps::farthest_points(&paths, 6, seed)
        .into_iter()
        .map(|i| moved.means[i])
        .collect();
    let canonical: Vec<[f32; 3]> = fps::farthest_points(&moved.means, 6, seed)
        .into_iter()
        .map(|i| moved.means[i])
        .collect();
    assert_ne!(expected, canonical, "the motion changes the picks");
    b.gaussians_changed(moved.view()).unwrap();
    assert_eq!(b.control_positions(), expected.as_slice());
    assert!(b.control_radii().iter().all(|r| r.is_finite() && *r > 0.0));
}
