//! Finite-difference checks of the EvoGS loss path into the backbone's parameters: for
//! `L = Σ w·d + λ1 L_sup + λ2 L_prior` at a frame with a full history (h = 3), the gradients the
//! backbone returns for Φ's buffers (fixed gain: K is a constant) and for Ψ (learned gain: its
//! inputs are constants) match central differences of `L` recomputed from the public pieces (Φ's
//! forward, evo-state's read-only forward and DESIGN §4.11's loss formulas, summed in f64). With the
//! history re-queried from Φ, d̂ is a function of Φ at the history times, so Φ's gradients include
//! the paths through d̂ (the rendering loss and L_sup; L_prior's d̂ is held at its value: the
//! stop-gradient).

use evogs_backbones::{
    Backbone, DEFORM_DIM, EvoBackbone, Gain, HistoryMode, Layout, PerGaussianState,
};
use evogs_train::{Method, Preset, TrainConfig};
use splat_raster::Gaussians;

const TIMES: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
const N: usize = 5;

/// A small deterministic generator in [-1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

fn gaussians(rng: &mut Lcg) -> Gaussians {
    let mut g = Gaussians::with_degree(0);
    for _ in 0..N {
        g.means.push([rng.next(), rng.next(), rng.next()]);
        g.log_scales.push([-2.0; 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(2.0 * rng.next());
        g.sh.extend([0.1, 0.2, 0.3]);
    }
    g
}

fn backbone(gain: Gain, components: Layout, history: HistoryMode) -> EvoBackbone {
    let mut c = TrainConfig::preset(Preset::Tiny);
    c.evogs.evo.history = history;
    c.method = Method::Evogs;
    c.net.width = 16;
    c.evogs.evo.gain = gain;
    c.evogs.evo.layout = components;
    c.evogs.triplane_channels = 2;
    c.evogs.triplane_resolutions = vec![4];
    c.evogs.bspline_controls = 5;
    c.evogs.bspline_width = 2;
    c.evogs.hidden_layers = 1;
    let mut b = EvoBackbone::new(&c.evogs, c.net.width, c.init_half_extent, c.seed).unwrap();
    b.prepare(&TIMES, N, 2.0).unwrap();
    b
}

fn sigmoid(x: f32) -> f64 {
    1.0 / (1.0 + (-x as f64).exp())
}

/// evo-state's read-only forward at `t` with Φ's observations (Φ also answers the re-queried
/// history times), and those observations.
fn evolve(b: &EvoBackbone, g: &Gaussians, t: f32) -> (evo_state::Step, Vec<f32>) {
    let pos: Vec<f32> = g.means.as_flattened().to_vec();
    let (z, _) = b.phi().forward(&pos, &[t; N], N).unwrap();
    let mut source =
        |time: f32, out: &mut [f32]| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
            out.copy_from_slice(&b.phi().forward(&pos, &[time; N], N)?.0);
            Ok(())
        };
    (b.evo().forward_with(t, &z, &mut source).unwrap(), z)
}

/// L recomputed from Φ, evo-state's read-only forward and DESIGN §4.11's formulas, with `sg_prior`
/// (when given) as the d̂ inside L_prior: the stop-gradient, for a finite difference that moves
/// Φ at the history times.
fn loss_with_prior(
    b: &mut EvoBackbone,
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
    render + 0.5 * sup / N as f64 + 0.5 * pri / N as f64
}

/// Randomises Φ's parameters (its output layer starts at zero) and commits frames 0..3.
fn setup(
    gain: Gain,
    components: Layout,
    history: HistoryMode,
    seed: u64,
) -> (EvoBackbone, Gaussians, Vec<f32>) {
    let mut rng = Lcg(seed);
    let mut b = backbone(gain, components, history);
    let names: Vec<String> = b.params().into_iter().map(|(n, _)| n).collect();
    for (name, mut p) in b.params_mut() {
        if name.starts_with("phi.") {
            let v: Vec<f32> = (0..p.len()).map(|_| 0.5 * rng.next()).collect();
            p.write_from(&v);
        }
    }
    assert!(names.iter().any(|n| n == "psi"), "{names:?}");
    let g = gaussians(&mut rng);
    for &t in &TIMES[..3] {
        b.forward(g.view(), t, true).unwrap();
        b.backward(&[0.0; N * DEFORM_DIM]).unwrap();
    }
    // Weights in [-2, 2): gradients well above the checks' absolute tolerance.
    let w: Vec<f32> = (0..N * DEFORM_DIM).map(|_| 2.0 * rng.next()).collect();
    (b, g, w)
}

fn check(gain: Gain, components: Layout, buffers: &dyn Fn(&str) -> bool) {
    check_history(gain, components, HistoryMode::Buffer, buffers);
}

fn check_history(
    gain: Gain,
    components: Layout,
    history: HistoryMode,
    buffers: &dyn Fn(&str) -> bool,
) {
    let t = TIMES[3];
    let (mut b, g, w) = setup(gain, components, history, 11);
    assert_eq!(b.evo().history(t).frames(), &[2, 1, 0]);
    let sg_prior = evolve(&b, &g, t).0.prior().unwrap().to_vec();
    let eps = 1e-3f32;
    let mut numeric = Vec::new();
    let buffer_names: Vec<(usize, String, usize)> = b
        .params()
        .into_iter()
        .enumerate()
        .filter(|(_, (n, _))| buffers(n))
        .map(|(k, (n, p))| (k, n, p.len()))
        .collect();
    assert!(!buffer_names.is_empty());
    for (k, name, len) in &buffer_names {
        // Spread over the buffer, plus its last values (Ψ's output layer and bias).
        let picks: Vec<usize> = (0..8)
            .map(|j| (j * 7919 + 3) % len)
            .chain(len.saturating_sub(4)..*len)
            .collect();
        for &i in &picks {
            let orig = b.params()[*k].1.get(i);
            let at = |v: f32, b: &mut EvoBackbone| {
                b.params_mut()[*k].1.write_at(i, &[v]);
                loss_with_prior(b, &g, &w, t, Some(&sg_prior))
            };
            let plus = at(orig + eps, &mut b);
            let minus = at(orig - eps, &mut b);
            at(orig, &mut b);
            numeric.push((name.clone(), *k, i, (plus - minus) / (2.0 * eps as f64)));
        }
    }
    b.forward(g.view(), t, true).unwrap();
    let grads = b.backward(&w).unwrap();
    let mut largest = 0.0f64;
    for (name, k, i, fd) in numeric {
        let a = grads[k][i] as f64;
        largest = largest.max(a.abs());
        assert!(
            (a - fd).abs() <= 2e-3 + 3e-2 * a.abs().max(fd.abs()),
            "{name}[{i}]: analytic {a} vs finite difference {fd}"
        );
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
    check(Gain::Learned, Layout::default(), &|n| n == "psi");
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
    check(Gain::Learned, every_component(), &|n| n == "psi");
}

#[test]
fn appearance_only_components_fill_their_columns_and_nothing_else() {
    // Opacity and colour alone: D = 4; the geometric columns stay zero, the appearance ones
    // carry Φ's output (Φ randomised by `setup`).
    let comps: Layout = "opacity,colour".parse().unwrap();
    let (mut b, g, _) = setup(Gain::Fixed(0.3), comps, HistoryMode::Buffer, 5);
    assert_eq!(b.evo().dim(), 4);
    let d = b.forward(g.view(), TIMES[3], false).unwrap();
    assert_eq!(d.len(), N * DEFORM_DIM);
    for row in d.chunks_exact(DEFORM_DIM) {
        assert!(row[..10].iter().all(|&v| v == 0.0), "{row:?}");
    }
    assert!(
        d.chunks_exact(DEFORM_DIM)
            .any(|r| r[10..].iter().any(|&v| v != 0.0))
    );
    let a = b.appearance();
    assert!(a.opacity && a.colour);
    // Geometry only: no appearance column is used.
    let (b, _, _) = setup(Gain::Fixed(0.3), Layout::default(), HistoryMode::Buffer, 5);
    assert_eq!(b.appearance(), Default::default());
}
