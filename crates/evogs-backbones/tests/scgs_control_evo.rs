//! EvoGS(SC-GS) with the evolution state on the control points ([`ScgsControlEvo`]):
//! finite-difference checks of its gradients and the life of its state.
//!
//! For `L = Σ w·d + λ1 L_sup + λ2 L_prior + ARAP` at a frame with a full history (h = 3), where
//! `d` are the skinned rows of five Gaussians and L_sup, L_prior run over the four control
//! points' evolved rows (weight 1 each), the backbone's gradients for the network, the control
//! points' positions, radii and weight logits (fixed gain) and for Ψ (learned gain) match central
//! differences of `L` recomputed from public pieces: the backbone's read-only forward, its
//! observations at the control points ([`ScgsControlEvo::observations_at`]), evo-state's
//! read-only forward and DESIGN §4.11's formulas, and the ARAP term from a baseline twin
//! ([`ScgsBackbone`] with the same seed and parameters). Re-queried history adds the paths
//! through d̂ (L_prior's d̂ held: the stop-gradient).

mod common;

use common::Lcg;
use evogs_backbones::{
    Backbone, EvoSettings, EvolutionOn, Gain, HistoryMode, Layout, PerGaussianState, ScgsBackbone,
    ScgsControlEvo, ScgsSettings,
};
use splat_core::Gaussians;

const TIMES: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
/// Gaussians.
const N: usize = 5;
/// Control points.
const M: usize = 4;
const HALF_EXTENT: f32 = 1.3;
const SEED: u64 = 0;

fn gaussians(rng: &mut Lcg) -> Gaussians {
    common::gaussians(N, rng)
}

fn settings() -> ScgsSettings {
    ScgsSettings {
        control_points: M,
        neighbours: 3,
        width: 8,
        depth: 2,
        xyz_freqs: 2,
        t_freqs: 2,
        arap_weight: 0.5,
        position_lr_scale: 1.0,
        follow_densify: false,
        placement: evogs_backbones::Placement::Canonical,
        evolution_on: EvolutionOn::Controls,
    }
}

fn evogs(gain: Gain, components: Layout, history: HistoryMode) -> EvoSettings {
    let mut e = EvoSettings::default();
    e.evo.history = history;
    e.evo.gain = gain;
    e.evo.layout = components;
    e
}

/// The backbone with random parameters (its heads start at zero) and frames 0..3 committed.
fn setup(e: &EvoSettings, seed: u64) -> (ScgsControlEvo, Gaussians, Vec<f32>) {
    let mut rng = Lcg(seed);
    let mut b = ScgsControlEvo::new(&settings(), e, HALF_EXTENT, SEED).unwrap();
    b.prepare(&TIMES, N, 2.0).unwrap();
    for (name, mut p) in b.params_mut() {
        let (centre, half) = match name.as_str() {
            "psi" => continue,
            "phi.controls.position" => (0.0, 0.8),
            "phi.controls.log_radius" => (-0.7, 0.2),
            _ => (0.0, 0.5),
        };
        let v: Vec<f32> = (0..p.len()).map(|_| centre + half * rng.next()).collect();
        p.write_from(&v);
    }
    let g = gaussians(&mut rng);
    for &t in &TIMES[..3] {
        b.forward(g.view(), t, true).unwrap();
        b.backward(&[0.0; N * 10]).unwrap();
    }
    let w: Vec<f32> = (0..N * 10).map(|_| 2.0 * rng.next()).collect();
    (b, g, w)
}

/// The weighted ARAP term at `t` of a baseline twin holding `b`'s network and control points.
fn arap(b: &ScgsControlEvo, g: &Gaussians, t: f32) -> f64 {
    let mut twin = ScgsBackbone::new(&settings(), HALF_EXTENT, SEED).unwrap();
    let src = b.params();
    {
        let mut dst = twin.params_mut();
        assert_eq!(dst.len() + 1, src.len());
        for ((_, s), (_, d)) in src.iter().zip(dst.iter_mut()) {
            d.write_from(&s.to_vec_f32());
        }
    }
    twin.forward(g.view(), t, true).unwrap();
    twin.backward(&[0.0; N * 10]).unwrap();
    twin.loss_terms()
}

/// L recomputed from public pieces (module docs), `sg_prior` as L_prior's d̂ when given.
fn loss(
    b: &mut ScgsControlEvo,
    g: &Gaussians,
    w: &[f32],
    t: f32,
    sg_prior: Option<&[f32]>,
    e: &EvoSettings,
) -> f64 {
    let d = b.forward(g.view(), t, false).unwrap();
    let z = b.observations_at(t).unwrap();
    let step = {
        let b: &ScgsControlEvo = b;
        let mut source =
            |time: f32, out: &mut [f32]| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
                out.copy_from_slice(&b.observations_at(time)?);
                Ok(())
            };
        b.evo().forward_with(t, &z, &mut source).unwrap()
    };
    let prior = sg_prior.unwrap_or_else(|| step.prior().unwrap());
    let corrected = step.corrected();
    let render: f64 = d.iter().zip(w).map(|(&a, &b)| a as f64 * b as f64).sum();
    let (mut sup, mut pri) = (0.0, 0.0);
    for k in 0..z.len() {
        sup += (corrected[k] as f64 - z[k] as f64).powi(2);
        pri += (prior[k] as f64 - z[k] as f64).powi(2);
    }
    render
        + e.evo.lambda_sup as f64 * sup / M as f64
        + e.evo.lambda_prior as f64 * pri / M as f64
        + arap(b, g, t)
}

fn check(gain: Gain, components: Layout, history: HistoryMode, buffers: &dyn Fn(&str) -> bool) {
    let e = evogs(gain, components, history);
    let t = TIMES[3];
    let grads = {
        let (mut b, g, w) = setup(&e, 11);
        b.forward(g.view(), t, true).unwrap();
        b.backward(&w).unwrap()
    };
    let (mut b, g, w) = setup(&e, 11);
    assert_eq!(b.evo().history(t).frames(), &[2, 1, 0]);
    assert_eq!(b.evo().rows(), M);
    let sg_prior = {
        let z = b.observations_at(t).unwrap();
        let bb: &ScgsControlEvo = &b;
        let mut source =
            |time: f32, out: &mut [f32]| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
                out.copy_from_slice(&bb.observations_at(time)?);
                Ok(())
            };
        let step = bb.evo().forward_with(t, &z, &mut source).unwrap();
        step.prior().unwrap().to_vec()
    };
    let eps = 1e-3f32;
    let picked: Vec<(usize, String, usize)> = b
        .params()
        .into_iter()
        .enumerate()
        .filter(|(_, (n, _))| buffers(n))
        .map(|(k, (n, p))| (k, n, p.len()))
        .collect();
    assert!(!picked.is_empty());
    let mut largest = 0.0f64;
    for (k, name, len) in &picked {
        let mut by_size: Vec<usize> = (0..*len).collect();
        by_size.sort_by(|&i, &j| grads[*k][j].abs().total_cmp(&grads[*k][i].abs()));
        let mut at_indices: Vec<usize> = (0..8)
            .map(|j| (j * 7919 + 3) % len)
            .chain(len.saturating_sub(4)..*len)
            .chain(by_size.into_iter().take(4))
            .collect();
        at_indices.sort_unstable();
        at_indices.dedup();
        for &i in &at_indices {
            let orig = b.params()[*k].1.get(i);
            let mut at = |v: f32| {
                b.params_mut()[*k].1.write_at(i, &[v]);
                loss(&mut b, &g, &w, t, Some(&sg_prior), &e)
            };
            let plus = at(orig + eps);
            let minus = at(orig - eps);
            at(orig);
            let fd = (plus - minus) / (2.0 * eps as f64);
            let a = grads[*k][i] as f64;
            largest = largest.max(a.abs());
            assert!(
                (a - fd).abs() <= 2e-3 + 3e-2 * a.abs().max(fd.abs()),
                "{name}[{i}]: analytic {a} vs finite difference {fd}"
            );
        }
    }
    assert!(largest > 1e-2, "every checked gradient is ~0 ({largest})");
}

fn is_phi(name: &str) -> bool {
    name.starts_with("phi.")
}

#[test]
fn network_and_control_gradients_match_finite_differences_with_a_fixed_gain() {
    check(
        Gain::Fixed(0.3),
        Layout::default(),
        HistoryMode::Buffer,
        &is_phi,
    );
}

#[test]
fn psi_gradients_match_finite_differences_with_the_learned_gain() {
    check(
        Gain::Learned,
        Layout::default(),
        HistoryMode::Buffer,
        &|n| n == "psi",
    );
}

#[test]
fn gradients_through_the_requeried_history_match_finite_differences() {
    check(
        Gain::Fixed(0.3),
        Layout::default(),
        HistoryMode::Requery,
        &is_phi,
    );
}

/// Only the translation evolves: the rotation and scale heads reach the skinning unchanged, and
/// their gradient still comes back.
#[test]
fn gradients_with_the_position_only_evolving_match_finite_differences() {
    let position = Layout {
        position: true,
        rotation: false,
        scale: false,
        opacity: false,
        colour: false,
    };
    check(Gain::Fixed(0.3), position, HistoryMode::Buffer, &is_phi);
}

#[test]
fn the_state_has_a_row_per_control_point_and_survives_save_and_load() {
    let e = evogs(Gain::Learned, Layout::default(), HistoryMode::Buffer);
    let (mut b, g, _) = setup(&e, 3);
    assert_eq!(b.rows(), M);
    assert!(b.state_bytes() > 0);
    // Densification finds no per-Gaussian arrays, and the Gaussians' count may change freely.
    assert!(b.rows_mut().is_empty());
    let dir = std::env::temp_dir().join(format!("evogs-control-evo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("evo_state.safetensors");
    b.save_state(&path).unwrap();
    let want = b.forward(g.view(), 0.6, false).unwrap();
    let mut c = ScgsControlEvo::new(&settings(), &e, HALF_EXTENT, SEED).unwrap();
    for ((_, s), (_, mut d)) in b.params().into_iter().zip(c.params_mut()) {
        d.write_from(&s.to_vec_f32());
    }
    c.load_state(&path).unwrap();
    assert_eq!(c.forward(g.view(), 0.6, false).unwrap(), want);
    // A state of another number of control points is refused, naming the field.
    let mut other = settings();
    other.control_points = M + 1;
    let mut d = ScgsControlEvo::new(&other, &e, HALF_EXTENT, SEED).unwrap();
    let err = d.load_state(&path).unwrap_err().to_string();
    assert!(
        err.contains("rows") && err.contains("control points"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn placing_the_control_points_again_keeps_their_state_rows() {
    let e = evogs(Gain::Learned, Layout::default(), HistoryMode::Buffer);
    let mut s = settings();
    s.follow_densify = true;
    let mut b = ScgsControlEvo::new(&s, &e, HALF_EXTENT, SEED).unwrap();
    b.prepare(&TIMES, N, 2.0).unwrap();
    let mut rng = Lcg(5);
    let g = gaussians(&mut rng);
    b.initialise(g.view()).unwrap();
    for &t in &TIMES[..3] {
        b.forward(g.view(), t, true).unwrap();
        b.backward(&[0.1; N * 10]).unwrap();
    }
    let valid = b.evo().valid().iter().filter(|&&v| v).count();
    assert!(valid > 0);
    // More Gaussians: the control points are placed again, M rows with their parents' history.
    let mut more = g.clone();
    for i in 0..N {
        let m = g.means[i];
        more.means.push([m[0] + 0.05, m[1], m[2]]);
        more.log_scales.push(g.log_scales[i]);
        more.rotations.push(g.rotations[i]);
        more.opacity_logits.push(g.opacity_logits[i]);
        more.sh.extend([0.1, 0.2, 0.3]);
    }
    b.gaussians_changed(more.view()).unwrap();
    assert_eq!(b.rows(), M);
    assert_eq!(b.evo().history(TIMES[3]).frames(), &[2, 1, 0]);
    let d = b.forward(more.view(), TIMES[3], true).unwrap();
    assert_eq!(d.len(), 2 * N * 10);
    assert!(d.iter().all(|v| v.is_finite()));
    b.backward(&vec![0.1; 2 * N * 10]).unwrap();
    // A fresh placement starts the state empty.
    b.initialise(more.view()).unwrap();
    assert!(b.evo().history(TIMES[4]).frames().is_empty());
}
