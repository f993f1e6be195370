//! Finite-difference checks of the EvoGS loss path into the backbone's parameters: for
//! `L = Σ w·d + λ1 L_sup + λ2 L_prior + R_Φ` at a frame with a full history (h = 3), the gradients
//! the backbone returns for Φ's buffers (fixed gain: K is a constant) and for Ψ (learned gain: its
//! inputs are constants) match central differences of `L` recomputed from the public pieces (Φ's
//! forward, evo-state's read-only forward, DESIGN §4.11's loss formulas and Φ's own regulariser
//! `R_Φ`, summed in f64). With the history re-queried from Φ, d̂ is a function of Φ at the history
//! times, so Φ's gradients include the paths through d̂ (the rendering loss and L_sup; L_prior's d̂
//! is held at its value: the stop-gradient).
//!
//! Each Φ that [`EvoBackbone`] wraps is checked: EvoGS(D-3DGS)'s tri-plane Φ, EvoGS(Grid4D)'s
//! hash-grid field ([`Grid4dPhi`], whose smoothness regulariser is `R_Φ`), EvoGS(4DGS)'s
//! HexPlane field ([`HexPhi`], its plane regularisers) and EvoGS(SC-GS)'s skinning
//! ([`ScgsPhi`], its ARAP loss), at small sizes.

mod common;

use common::Lcg;
use evogs_backbones::evo_backbone::observation_config;
use evogs_backbones::scgs::phi::ScgsPhi;
use evogs_backbones::{
    Backbone, EvoBackbone, EvoSettings, Gain, Grid4dLr, Grid4dPhi, Grid4dRun, HexPhi, HistoryMode,
    Layout, Observer, PerGaussianState, ScgsSettings,
};
use splat_core::Gaussians;
use tiny_nn::ObservationNet;

const TIMES: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
const N: usize = 5;

fn gaussians(rng: &mut Lcg) -> Gaussians {
    common::gaussians(N, rng)
}

/// What a run hands the backbone: its EvoGS settings, the baseline network's width, the half
/// extent of its initial cube and its seed (the trainer's `tiny` preset's, at width 16).
struct RunConfig {
    evogs: EvoSettings,
    width: usize,
    init_half_extent: f32,
    seed: u64,
}

/// One Φ of EvoGS: how a test run's config makes it, and how its parameters are randomised.
struct Case<P: Observer> {
    /// Φ for the config (also Φ's twin that evaluates its regulariser).
    phi: fn(&RunConfig) -> P,
    /// Centre and half-width of the uniform values Φ's buffer `name` is set to.
    init: fn(&str) -> (f32, f32),
}

/// EvoGS(D-3DGS)'s tri-plane Φ (what [`EvoBackbone::new`] builds).
fn triplane() -> Case<ObservationNet> {
    Case {
        phi: |c| {
            ObservationNet::new(observation_config(
                &c.evogs,
                c.width,
                c.init_half_extent,
                c.seed,
            ))
            .unwrap()
        },
        init: |_| (0.0, 0.5),
    }
}

/// EvoGS(Grid4D)'s Φ at width 8 (half the run's 16) with 2^5-entry tables: every level collides.
fn grid4d() -> Case<Grid4dPhi> {
    Case {
        phi: |c| {
            let run = Grid4dRun {
                width: c.width,
                log2_table: 5,
                half_extent: c.init_half_extent,
                lr: Grid4dLr {
                    position_init: 1.6e-4,
                    position_final: 1.6e-6,
                    delay_mult: 0.01,
                    max_steps: 100,
                    scale: 1.0,
                },
                seed: c.seed,
            };
            Grid4dPhi::new(&run, &c.evogs).unwrap()
        },
        init: |_| (0.0, 0.5),
    }
}

/// EvoGS(4DGS)'s Φ (4DGaussians' D-NeRF planes, feature layer at half width). Its planes start
/// near 1 (as 4DGaussians' time planes): six plane features multiply, and values around 0 would
/// make every plane gradient vanish below the check's tolerance. Its plane regularisers are in
/// L, but at 4DGaussians' weights (1e-4, 1e-2, 1e-4 on means over every plane entry) their share
/// of one entry's gradient is far below the tolerance: leaving them out of L does not fail these
/// checks (it fails Grid4D's); tiny-nn's `hexplane` and `hexfield` tests check them.
fn hexplane() -> Case<HexPhi> {
    Case {
        phi: |c| HexPhi::new(&c.evogs, c.init_half_extent, c.seed).unwrap(),
        init: |name| {
            if name == "hexplane" {
                (1.0, 0.3)
            } else {
                (0.0, 0.5)
            }
        },
    }
}

/// EvoGS(SC-GS)'s Φ: four control points (K = 3) with a small network at low frequencies, their
/// positions learning (so their gradient is checked too), the ARAP term weighted so that it
/// counts in L.
fn scgs() -> Case<ScgsPhi> {
    Case {
        phi: |c| {
            let settings = ScgsSettings {
                control_points: 4,
                neighbours: 3,
                width: 8,
                depth: 2,
                xyz_freqs: 2,
                t_freqs: 2,
                arap_weight: 0.5,
                position_lr_scale: 1.0,
                follow_densify: false,
                placement: evogs_backbones::Placement::Canonical,
                evolution_on: evogs_backbones::EvolutionOn::Gaussians,
            };
            ScgsPhi::new(&settings, &c.evogs, c.init_half_extent, c.seed).unwrap()
        },
        init: |name| match name {
            "controls.position" => (0.0, 0.8),
            "controls.log_radius" => (-0.7, 0.2),
            _ => (0.0, 0.5),
        },
    }
}

fn config(gain: Gain, components: Layout, history: HistoryMode) -> RunConfig {
    let mut c = RunConfig {
        evogs: EvoSettings::default(),
        width: 16,
        init_half_extent: 1.3,
        seed: 0,
    };
    c.evogs.evo.history = history;
    c.evogs.evo.gain = gain;
    c.evogs.evo.layout = components;
    c.evogs.triplane_channels = 2;
    c.evogs.triplane_resolutions = vec![4];
    c.evogs.bspline_controls = 5;
    c.evogs.bspline_width = 2;
    c.evogs.hidden_layers = 1;
    c
}

fn backbone<P: Observer>(case: &Case<P>, c: &RunConfig) -> EvoBackbone<P> {
    let mut b = EvoBackbone::with_phi(&c.evogs, c.seed, (case.phi)(c)).unwrap();
    b.prepare(&TIMES, N, 2.0).unwrap();
    b
}

fn sigmoid(x: f32) -> f64 {
    1.0 / (1.0 + (-x as f64).exp())
}

/// evo-state's read-only forward at `t` with Φ's observations (Φ also answers the re-queried
/// history times), and those observations.
fn evolve<P: Observer>(b: &EvoBackbone<P>, g: &Gaussians, t: f32) -> (evo_state::Step, Vec<f32>) {
    let pos: Vec<f32> = g.means.as_flattened().to_vec();
    let (z, _) = b.phi().observe(&pos, &[t; N], N).unwrap();
    let mut source =
        |time: f32, out: &mut [f32]| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            out.copy_from_slice(&b.phi().observe(&pos, &[time; N], N)?.0);
            Ok(())
        };
    (b.evo().forward_with(t, &z, &mut source).unwrap(), z)
}

/// Φ's own regulariser (weighted) at the backbone's Φ parameters, on its observation of `g` at
/// `t` (the training forward's): evaluated by a twin of Φ made as the case makes it (same seeds,
/// so the same sampled rows) and given the backbone's Φ parameters.
fn phi_regulariser<P: Observer>(
    case: &Case<P>,
    c: &RunConfig,
    b: &EvoBackbone<P>,
    g: &Gaussians,
    t: f32,
) -> f64 {
    let mut twin = (case.phi)(c);
    for ((_, src), (_, mut dst)) in b
        .phi()
        .named_params()
        .into_iter()
        .zip(twin.named_params_mut())
    {
        dst.write_from(&src.to_vec_f32());
    }
    let pos: Vec<f32> = g.means.as_flattened().to_vec();
    let (_, cache) = twin.observe(&pos, &[t; N], N).unwrap();
    let mut grads: Vec<Vec<f32>> = twin
        .named_params()
        .iter()
        .map(|(_, p)| vec![0.0; p.len()])
        .collect();
    twin.regularise(&cache, &mut grads).unwrap()
}

/// L recomputed from Φ, evo-state's read-only forward, DESIGN §4.11's formulas and Φ's
/// regulariser, with `sg_prior` (when given) as the d̂ inside L_prior: the stop-gradient, for a
/// finite difference that moves Φ at the history times.
fn loss_with_prior<P: Observer>(
    case: &Case<P>,
    c: &RunConfig,
    b: &mut EvoBackbone<P>,
    g: &Gaussians,
    w: &[f32],
    t: f32,
    sg_prior: Option<&[f32]>,
) -> f64 {
    let d = b.forward(g.view(), t, false).unwrap();
    let (step, z) = evolve(b, g, t);
    let prior = sg_prior.unwrap_or_else(|| step.prior().unwrap());
    let corrected = step.corrected();
    let dim = z.len() / N;
    let render: f64 = d.iter().zip(w).map(|(&a, &b)| a as f64 * b as f64).sum();
    let (mut sup, mut pri) = (0.0, 0.0);
    for i in 0..N {
        for j in 0..dim {
            let e = i * dim + j;
            sup += (corrected[e] as f64 - z[e] as f64).powi(2);
            pri += sigmoid(g.opacity_logits[i]) * (prior[e] as f64 - z[e] as f64).powi(2);
        }
    }
    let s = b.settings();
    render
        + s.evo.lambda_sup as f64 * sup / N as f64
        + s.evo.lambda_prior as f64 * pri / N as f64
        + phi_regulariser(case, c, b, g, t)
}

/// Randomises Φ's parameters (its output layer starts at zero) and commits frames 0..3.
fn setup<P: Observer>(
    case: &Case<P>,
    c: &RunConfig,
    seed: u64,
) -> (EvoBackbone<P>, Gaussians, Vec<f32>) {
    let mut rng = Lcg(seed);
    let mut b = backbone(case, c);
    let names: Vec<String> = b.params().into_iter().map(|(n, _)| n).collect();
    for (name, mut p) in b.params_mut() {
        if let Some(phi) = name.strip_prefix("phi.") {
            let (centre, half) = (case.init)(phi);
            let v: Vec<f32> = (0..p.len()).map(|_| centre + half * rng.next()).collect();
            p.write_from(&v);
        }
    }
    assert!(names.iter().any(|n| n == "psi"), "{names:?}");
    let g = gaussians(&mut rng);
    for &t in &TIMES[..3] {
        b.forward(g.view(), t, true).unwrap();
        b.backward(&vec![0.0; N * c.evogs.evo.layout.dim()])
            .unwrap();
    }
    // Weights in [-2, 2): gradients well above the checks' absolute tolerance.
    let w: Vec<f32> = (0..N * c.evogs.evo.layout.dim())
        .map(|_| 2.0 * rng.next())
        .collect();
    (b, g, w)
}

fn check(gain: Gain, components: Layout, buffers: &dyn Fn(&str) -> bool) {
    check_phi(&triplane(), gain, components, HistoryMode::Buffer, buffers);
}

fn check_history(
    gain: Gain,
    components: Layout,
    history: HistoryMode,
    buffers: &dyn Fn(&str) -> bool,
) {
    check_phi(&triplane(), gain, components, history, buffers);
}

/// The backbone's gradients of the buffers `buffers` selects against central differences of L:
/// at spread indices, each buffer's last values (Ψ's output layer and bias) and the indices of
/// its four largest analytic gradients (what 5 Gaussians touch of a hash table or a plane).
fn check_phi<P: Observer>(
    case: &Case<P>,
    gain: Gain,
    components: Layout,
    history: HistoryMode,
    buffers: &dyn Fn(&str) -> bool,
) {
    let c = config(gain, components, history);
    let t = TIMES[3];
    // The analytic gradients first, on a copy (a training step commits frame 3).
    let grads = {
        let (mut b, g, w) = setup(case, &c, 11);
        b.forward(g.view(), t, true).unwrap();
        b.backward(&w).unwrap()
    };
    let (mut b, g, w) = setup(case, &c, 11);
    assert_eq!(b.evo().history(t).frames(), &[2, 1, 0]);
    let sg_prior = evolve(&b, &g, t).0.prior().unwrap().to_vec();
    let eps = 1e-3f32;
    let buffer_names: Vec<(usize, String, usize)> = b
        .params()
        .into_iter()
        .enumerate()
        .filter(|(_, (n, _))| buffers(n))
        .map(|(k, (n, p))| (k, n, p.len()))
        .collect();
    assert!(!buffer_names.is_empty());
    let mut largest = 0.0f64;
    for (k, name, len) in &buffer_names {
        let mut by_size: Vec<usize> = (0..*len).collect();
        by_size.sort_by(|&i, &j| grads[*k][j].abs().total_cmp(&grads[*k][i].abs()));
        let mut picks: Vec<usize> = (0..8)
            .map(|j| (j * 7919 + 3) % len)
            .chain(len.saturating_sub(4)..*len)
            .chain(by_size.into_iter().take(4))
            .collect();
        picks.sort_unstable();
        picks.dedup();
        for &i in &picks {
            let orig = b.params()[*k].1.get(i);
            let at = |v: f32, b: &mut EvoBackbone<P>| {
                b.params_mut()[*k].1.write_at(i, &[v]);
                loss_with_prior(case, &c, b, &g, &w, t, Some(&sg_prior))
            };
            let plus = at(orig + eps, &mut b);
            let minus = at(orig - eps, &mut b);
            at(orig, &mut b);
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

#[test]
fn phi_gradients_match_finite_differences_with_a_fixed_gain() {
    check(Gain::Fixed(0.3), Layout::default(), &|n| {
        n.starts_with("phi.")
    });
}

#[test]
fn psi_gradients_match_finite_differences_with_the_learned_gain() {
    check(Gain::Learned, Layout::default(), &is_psi);
}

/// "Without buffer": Φ's gradients include the paths through the re-queried prior.
#[test]
fn phi_gradients_through_the_requeried_history_match_finite_differences() {
    check_history(
        Gain::Fixed(0.3),
        Layout::default(),
        HistoryMode::Requery,
        &|n| n.starts_with("phi."),
    );
}

fn every_component() -> Layout {
    "pos,rot,scale,opacity,colour".parse().unwrap()
}

#[test]
fn phi_gradients_through_opacity_and_colour_match_finite_differences() {
    check(Gain::Fixed(0.3), every_component(), &|n| {
        n.starts_with("phi.")
    });
}

#[test]
fn psi_gradients_with_opacity_and_colour_match_finite_differences() {
    check(Gain::Learned, every_component(), &is_psi);
}

#[test]
fn appearance_only_components_give_rows_of_their_own_layout() {
    // Opacity and colour alone: D = 4, rows of 4 values (opacity, then the SH DC) carrying the
    // corrected d̃ as it is (Φ randomised by `setup`).
    let comps: Layout = "opacity,colour".parse().unwrap();
    let c = config(Gain::Fixed(0.3), comps, HistoryMode::Buffer);
    let (mut b, g, _) = setup(&triplane(), &c, 5);
    assert_eq!(b.evo().dim(), 4);
    assert_eq!(b.layout(), comps);
    let d = b.forward(g.view(), TIMES[3], false).unwrap();
    assert_eq!(d, evolve(&b, &g, TIMES[3]).0.corrected());
    assert_eq!(d.len(), N * 4);
    assert!(d.iter().any(|&v| v != 0.0));
    // A gradient of another width is refused, naming both.
    b.forward(g.view(), TIMES[3], true).unwrap();
    let e = b.backward(&[0.0; N * 10]).unwrap_err().to_string();
    assert!(e.contains("50 values") && e.contains("5 × 4"), "{e}");
    // Geometry only: position, rotation, scale.
    let c = config(Gain::Fixed(0.3), Layout::default(), HistoryMode::Buffer);
    let (b, _, _) = setup(&triplane(), &c, 5);
    assert_eq!(b.layout(), Layout::GEOMETRY);
}

fn is_phi(name: &str) -> bool {
    name.starts_with("phi.")
}

fn is_psi(name: &str) -> bool {
    name == "psi"
}

/// EvoGS(Grid4D): every buffer of the hash-grid Φ (four tables, attention, temporal MLP, heads),
/// its smoothness regulariser included.
#[test]
fn grid4d_phi_gradients_match_finite_differences_with_a_fixed_gain() {
    let c = Layout::default();
    check_phi(&grid4d(), Gain::Fixed(0.3), c, HistoryMode::Buffer, &is_phi);
}

#[test]
fn grid4d_psi_gradients_match_finite_differences_with_the_learned_gain() {
    let c = Layout::default();
    check_phi(&grid4d(), Gain::Learned, c, HistoryMode::Buffer, &is_psi);
}

#[test]
fn grid4d_phi_gradients_through_the_requeried_history_match_finite_differences() {
    let c = Layout::default();
    check_phi(
        &grid4d(),
        Gain::Fixed(0.3),
        c,
        HistoryMode::Requery,
        &is_phi,
    );
}

/// Grid4D's Φ has a head per component, opacity and colour included.
#[test]
fn grid4d_phi_gradients_through_opacity_and_colour_match_finite_differences() {
    let c = every_component();
    check_phi(&grid4d(), Gain::Fixed(0.3), c, HistoryMode::Buffer, &is_phi);
}

/// EvoGS(4DGS): the planes (their regularisers included), feature layer and three heads.
#[test]
fn hexplane_phi_gradients_match_finite_differences_with_a_fixed_gain() {
    let c = Layout::default();
    check_phi(
        &hexplane(),
        Gain::Fixed(0.3),
        c,
        HistoryMode::Buffer,
        &is_phi,
    );
}

#[test]
fn hexplane_psi_gradients_match_finite_differences_with_the_learned_gain() {
    let c = Layout::default();
    check_phi(&hexplane(), Gain::Learned, c, HistoryMode::Buffer, &is_psi);
}

#[test]
fn hexplane_phi_gradients_through_the_requeried_history_match_finite_differences() {
    let c = Layout::default();
    check_phi(
        &hexplane(),
        Gain::Fixed(0.3),
        c,
        HistoryMode::Requery,
        &is_phi,
    );
}

/// EvoGS(SC-GS): the control-point network, positions, radii and weight logits through the
/// skinning, the ARAP regulariser included.
#[test]
fn scgs_phi_gradients_match_finite_differences_with_a_fixed_gain() {
    let c = Layout::default();
    check_phi(&scgs(), Gain::Fixed(0.3), c, HistoryMode::Buffer, &is_phi);
}

#[test]
fn scgs_psi_gradients_match_finite_differences_with_the_learned_gain() {
    let c = Layout::default();
    check_phi(&scgs(), Gain::Learned, c, HistoryMode::Buffer, &is_psi);
}

#[test]
fn scgs_phi_gradients_through_the_requeried_history_match_finite_differences() {
    let c = Layout::default();
    check_phi(&scgs(), Gain::Fixed(0.3), c, HistoryMode::Requery, &is_phi);
}
