//! evo-state without any splatting: points on smooth trajectories, observed with noise at every
//! frame by a "network" (here: truth + Gaussian noise), smoothed by the evolution.
//!
//! Prints the mean position error against ground truth for evolution off (d = z), fixed gains,
//! and the learned gain Ψ before and after a little training with tiny-nn's Adam. Ψ's training
//! signal is a stand-in for the render loss: dL/dd̃ of mean_i |d̃_i - x_i|², plus EvoGS's own
//! L_sup/L_prior. The history is a constant for autodiff, so this signal is myopic: it does not
//! see that a larger K makes later priors noisier, and L_sup pulls K towards 1. In this toy the
//! trained Ψ therefore ends above the best fixed gain (the output says by how much).
//!
//! Run: `cargo run --release -p evo-state --example smooth_points`

use evo_state::{EvoConfig, EvoState, Frames, Gain, Layout, Step};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Uniform};
use tiny_nn::{Adam, LrSchedule};

const POINTS: usize = 2000;
const FRAMES: usize = 60;
const NOISE: f32 = 0.05;

struct Scene {
    times: Vec<f32>,
    /// truth[k]: POINTS × 3 positions at frame k.
    truth: Vec<Vec<f32>>,
    /// Noisy observations, one fixed draw per frame and epoch.
    noisy: Vec<Vec<Vec<f32>>>,
}

fn scene(epochs: usize) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let u = Uniform::new(-1.0f32, 1.0).unwrap();
    let noise = Normal::new(0.0f32, NOISE).unwrap();
    // Non-uniform timestamps in [0, 1].
    let times: Vec<f32> = (0..FRAMES)
        .map(|k| {
            let s = k as f32 / (FRAMES - 1) as f32;
            s + 0.3 * s * (1.0 - s) * (5.0 * s).sin() / 5.0
        })
        .collect();
    let params: Vec<[f32; 9]> = (0..POINTS)
        .map(|_| std::array::from_fn(|_| u.sample(&mut rng)))
        .collect();
    let truth: Vec<Vec<f32>> = times
        .iter()
        .map(|&t| {
            params
                .iter()
                .flat_map(|p| {
                    let w = 2.0 + p[6];
                    [
                        p[0] + 0.5 * (w * t * 3.0 + p[3]).sin(),
                        p[1] + 0.5 * (w * t * 2.0 + p[4]).cos(),
                        p[2] + 0.4 * t * p[5] + 0.2 * (w * t * 4.0 + p[7]).sin() * p[8],
                    ]
                })
                .collect()
        })
        .collect();
    let noisy = (0..epochs)
        .map(|_| {
            truth
                .iter()
                .map(|x| x.iter().map(|v| v + noise.sample(&mut rng)).collect())
                .collect()
        })
        .collect();
    Scene {
        times,
        truth,
        noisy,
    }
}

fn rmse(a: &[f32], b: &[f32]) -> f64 {
    let s: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
    (s / (a.len() / 3) as f64).sqrt()
}

/// One pass over the frames in order (a training epoch). With `adam`, Ψ takes a step per frame.
/// Returns the mean error of d̃ against the truth over the pass.
fn epoch(
    state: &mut EvoState,
    scene: &Scene,
    e: usize,
    adam: Option<(&mut Adam, tiny_nn::GroupId, &mut i64)>,
) -> anyhow::Result<f64> {
    let mut adam = adam;
    let mut total = 0.0;
    for k in 0..FRAMES {
        let z = &scene.noisy[e][k];
        let step: Step = state.forward(scene.times[k], z)?;
        total += rmse(step.corrected(), &scene.truth[k]);
        if let Some((adam, group, iteration)) = adam.as_mut() {
            let n = POINTS as f32;
            let dl_dd: Vec<f32> = step
                .corrected()
                .iter()
                .zip(&scene.truth[k])
                .map(|(d, x)| 2.0 * (d - x) / n)
                .collect();
            let grads = state.backward(&step, z, &dl_dd, &vec![1.0; POINTS])?;
            if let Some(dpsi) = grads.dpsi {
                adam.step(
                    *group,
                    **iteration,
                    state.psi_mut().mlp_mut().params_mut(),
                    &dpsi,
                )?;
                **iteration += 1;
            }
        }
        state.commit(&step)?;
    }
    Ok(total / FRAMES as f64)
}

fn main() -> anyhow::Result<()> {
    let epochs = 12;
    let scene = scene(epochs + 1);
    let frames = Frames::new(scene.times.clone())?;
    let layout = Layout {
        position: true,
        rotation: false,
        scale: false,
        opacity: false,
        colour: false,
    };
    let base = EvoConfig {
        layout,
        extent: 2.0,
        ..EvoConfig::default()
    };
    let eval = epochs; // the last noise draw is held out for evaluation

    println!("{POINTS} points, {FRAMES} non-uniform frames, observation noise σ = {NOISE}");
    println!("mean RMS position error against ground truth (lower is better):");
    let off_err = {
        let mut st = EvoState::new(
            EvoConfig {
                evolution: false,
                ..base
            },
            frames.clone(),
            POINTS,
            1,
        )?;
        epoch(&mut st, &scene, eval, None)?
    };
    println!("  evolution off (d = z)        {off_err:.4}");
    // Fixed gains: a warm-up pass fills the buffer, then the held-out pass is measured.
    let mut best = (f64::INFINITY, 0.0f32);
    for k in [1.0f32, 0.5, 0.3, 0.2] {
        let mut st = EvoState::new(
            EvoConfig {
                gain: Gain::Fixed(k),
                ..base
            },
            frames.clone(),
            POINTS,
            1,
        )?;
        epoch(&mut st, &scene, 0, None)?;
        let err = epoch(&mut st, &scene, eval, None)?;
        println!("  evolution on, fixed K = {k:.1}   {err:.4}");
        if err < best.0 {
            best = (err, k);
        }
    }
    // Learned gain: train Ψ for a few passes, then measure on the held-out noise.
    let mut st = EvoState::new(base, frames.clone(), POINTS, 1)?;
    let mut adam = Adam::new();
    let group = adam.add_group("psi", st.psi().param_count(), 1, LrSchedule::Constant(3e-3))?;
    let mut iteration = 0i64;
    let before = {
        let mut probe = st.clone();
        epoch(&mut probe, &scene, 0, None)?;
        epoch(&mut probe, &scene, eval, None)?
    };
    println!("  evolution on, Ψ untrained    {before:.4}");
    for e in 0..epochs {
        epoch(&mut st, &scene, e, Some((&mut adam, group, &mut iteration)))?;
    }
    let learned = epoch(&mut st, &scene, eval, None)?;
    println!(
        "  evolution on, Ψ trained      {learned:.4}  ({epochs} passes, {iteration} Adam steps)"
    );
    let gain_mean = {
        let step = st.forward(scene.times[FRAMES - 1], &scene.noisy[eval][FRAMES - 1])?;
        let evo_state::Gains::Learned(k) = step.gains() else {
            anyhow::bail!("gain not learned")
        };
        k.iter().map(|&v| v as f64).sum::<f64>() / k.len() as f64
    };
    println!("  (mean learned K at the last frame: {gain_mean:.3})");
    let gain = |err: f64| 100.0 * (1.0 - err / off_err);
    println!(
        "error reduction over evolution off: best fixed K ({:.1}) {:.1}%, untrained Ψ {:.1}%, trained Ψ {:.1}%",
        best.1,
        gain(best.0),
        gain(before),
        gain(learned)
    );
    Ok(())
}
