//! The baseline's deformation network learns motion (issue Q; SC-GS's control points too): on a tiny scene whose only
//! Gaussians slide along x as time goes from 0 to 1, the D-3DGS MLP receives a non-zero gradient
//! from its first step and, after a short run, moves the Gaussians by the ground truth's
//! displacement. The canonical Gaussians start where the ground truth is at t = 0.5, so nothing
//! but the network can explain the images at other times.

use evogs_backbones::NetInit;
use evogs_io::{ImageRgb, Split};
use evogs_train::data::{SplitViews, View};
use evogs_train::{Method, Preset, TrainConfig, Trainer};
use glam::Vec3;
use splat_raster::{Camera, CpuRasterizer, Gaussians, Rasterizer, RenderOptions};

const SIZE: u32 = 32;
const FRAMES: usize = 16;
/// The ground truth moves by this much along x over t in [0, 1].
const TRAVEL: f32 = 0.6;

/// Three coloured Gaussians around `x` on the x axis (degree-0 SH).
fn blobs(x: f32) -> Gaussians {
    let means = vec![[x, 0.0, 0.0], [x, 0.35, 0.1], [x, -0.3, -0.2]];
    let n = means.len();
    Gaussians {
        sh_degree: 0,
        means,
        log_scales: vec![[0.12f32.ln(); 3]; n],
        rotations: vec![[1.0, 0.0, 0.0, 0.0]; n],
        opacity_logits: vec![3.0; n],
        sh: vec![1.5, 0.2, -1.0, -1.0, 1.5, 0.2, 0.2, -1.0, 1.5],
    }
}

fn ground_truth_x(t: f32) -> f32 {
    TRAVEL * (t - 0.5)
}

/// One view per frame, from a camera turning around the scene (never looking along x, where the
/// motion would be in depth only).
fn views() -> SplitViews {
    let raster = CpuRasterizer::new();
    let opts = RenderOptions {
        background: [0.0; 3],
        sh_degree: None,
    };
    let views = (0..FRAMES)
        .map(|k| {
            let t = k as f32 / (FRAMES - 1) as f32;
            let a = 1.0 + 2.3 * k as f32;
            let camera = Camera::look_at(
                SIZE,
                SIZE,
                0.9,
                Vec3::new(3.0 * a.cos(), 3.0 * a.sin(), 1.2),
                Vec3::ZERO,
                Vec3::Z,
            );
            let gt = blobs(ground_truth_x(t));
            let image = raster.forward(gt.view(), &camera, &opts).unwrap().color;
            View {
                path: format!("r_{k}.png").into(),
                image: ImageRgb {
                    width: SIZE,
                    height: SIZE,
                    pixels: image,
                },
                camera,
                time: t,
            }
        })
        .collect();
    SplitViews {
        split: Split::Train,
        views,
    }
}

fn config(iterations: u64) -> TrainConfig {
    let mut c = TrainConfig::preset(Preset::Dnerf).with_iterations(iterations);
    c.method = Method::Baseline;
    c.sh_degree = 0;
    c.net.width = 32;
    c.net.depth = 4;
    c.net.skip_after = Some(2);
    c.net.xyz_freqs = 4;
    // He with zero heads (a setting; the dnerf preset initialises as D-3DGS does).
    c.net.init = NetInit::He;
    // Deform from the first iteration, no densification: only the network can move things.
    c.warm_up = 1;
    c.densify.schedule.from = iterations + 1;
    c.densify.schedule.until = iterations + 1;
    c.densify.schedule.opacity_reset_interval = 100 * iterations;
    c
}

/// Mean x displacement of the three Gaussians at `t`.
fn mean_dx(trainer: &mut Trainer, t: f32) -> f32 {
    let canonical = trainer.state().gaussians().means.clone();
    let g = trainer.deformed_at(t).unwrap();
    g.means
        .iter()
        .zip(&canonical)
        .map(|(a, b)| a[0] - b[0])
        .sum::<f32>()
        / canonical.len() as f32
}

#[test]
fn the_deformation_network_gets_gradient_and_learns_the_motion() {
    let iterations = 600;
    let c = config(iterations);
    let mut trainer = Trainer::with_gaussians(c, views(), blobs(0.0)).unwrap();
    // Zero heads: the deformation starts at exactly zero.
    assert_eq!(mean_dx(&mut trainer, 0.0), 0.0);
    let first = trainer.step().unwrap();
    let g = first
        .net_grad_norm
        .expect("the network is used from iteration 1");
    assert!(g.is_finite() && g > 0.0, "gradient norm {g}");
    while trainer.iteration() < iterations {
        trainer.step().unwrap();
    }
    let travel = mean_dx(&mut trainer, 1.0) - mean_dx(&mut trainer, 0.0);
    assert!(
        (travel - TRAVEL).abs() < 0.15 * TRAVEL,
        "learned travel {travel}, ground truth {TRAVEL}"
    );
    // Half way, the Gaussians are about where the canonical ones are.
    let mid = mean_dx(&mut trainer, 0.5);
    assert!(mid.abs() < 0.15 * TRAVEL, "displacement at t = 0.5: {mid}");
}

/// SC-GS's backbone learns the same motion through its control points: the network runs on
/// three control points placed on the Gaussians, and the skinning carries their motion to them.
#[test]
fn sc_gs_control_points_learn_the_motion() {
    let iterations = 600;
    let mut c = config(iterations);
    c.backbone = evogs_train::BackboneKind::Scgs;
    c.backbones.scgs = evogs_backbones::ScgsSettings {
        control_points: 3,
        neighbours: 2,
        width: 32,
        depth: 4,
        xyz_freqs: 4,
        ..evogs_backbones::ScgsSettings::default()
    };
    let mut trainer = Trainer::with_gaussians(c, views(), blobs(0.0)).unwrap();
    assert_eq!(mean_dx(&mut trainer, 0.0), 0.0, "zero heads: no motion yet");
    let first = trainer.step().unwrap();
    let g = first
        .net_grad_norm
        .expect("the network is used from iteration 1");
    assert!(g.is_finite() && g > 0.0, "gradient norm {g}");
    while trainer.iteration() < iterations {
        trainer.step().unwrap();
    }
    let travel = mean_dx(&mut trainer, 1.0) - mean_dx(&mut trainer, 0.0);
    assert!(
        (travel - TRAVEL).abs() < 0.15 * TRAVEL,
        "learned travel {travel}, ground truth {TRAVEL}"
    );
}

/// Static Gaussians (away from the x axis) and the three moving ones of [`blobs`] at time `t`.
fn scene_with_static_part(t: f32) -> Gaussians {
    let mut g = blobs(ground_truth_x(t));
    for (p, c) in [
        ([0.0, 0.0, 0.7], [1.5, 1.5, -1.0]),
        ([0.0, 0.0, -0.75], [-1.0, 1.5, 1.5]),
        ([0.5, 0.6, 0.4], [1.5, 1.5, 1.5]),
        ([-0.5, -0.6, 0.45], [0.2, 0.2, 0.2]),
    ] {
        g.means.push(p);
        g.log_scales.push([0.1f32.ln(); 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(3.0);
        g.sh.extend(c);
    }
    g
}

/// The `dnerf` preset's own recipe, compressed to 1 500 iterations (D-3DGS's initialisation,
/// the static warm-up, densification, the rates; the network and the Gaussian cap are shrunk to
/// the scene to keep the test cheap) learns the motion of a moving part beside a static one:
/// after training, the Gaussians near the moving part's path follow the ground truth's travel
/// along x, and the static part stays where it is.
#[test]
fn the_dnerf_recipe_learns_a_moving_part_beside_a_static_one() {
    let iterations = 1_500;
    let mut c = TrainConfig::preset(Preset::Dnerf).with_iterations(iterations);
    c.method = Method::Baseline;
    c.net.width = 32;
    c.net.depth = 4;
    c.net.skip_after = Some(2);
    c.net.xyz_freqs = 4;
    // Degree 1 (zero higher bands): densification with degree 0 fails on the empty higher-band
    // Adam group (a bug of its own, not this test's subject).
    c.sh_degree = 1;
    // The preset's cap, scaled to the scene: a few Gaussians per blob.
    c.densify.max_gaussians = Some(40);
    let raster = CpuRasterizer::new();
    let opts = RenderOptions {
        background: [0.0; 3],
        sh_degree: None,
    };
    let mut train = views();
    for v in &mut train.views {
        let gt = scene_with_static_part(v.time);
        v.image.pixels = raster.forward(gt.view(), &v.camera, &opts).unwrap().color;
    }
    // Start from the ground truth at t = 0.5: only the network can explain the other times.
    let mut start = scene_with_static_part(0.5);
    start.sh = start
        .sh
        .chunks_exact(3)
        .flat_map(|dc| dc.iter().copied().chain([0.0; 9]))
        .collect();
    start.sh_degree = 1;
    let mut trainer = Trainer::with_gaussians(c, train, start).unwrap();
    while trainer.iteration() < iterations {
        trainer.step().unwrap();
    }
    let canonical = trainer.state().gaussians().clone();
    let (d0, d1) = (
        trainer.deformed_at(0.0).unwrap(),
        trainer.deformed_at(1.0).unwrap(),
    );
    let travel = |i: usize| d1.means[i][0] - d0.means[i][0];
    let opaque = |i: usize| canonical.opacity_logits[i] > 0.0;
    // Near the moving part's path: within its blobs' reach of the x axis (the static part is
    // farther away).
    let moving: Vec<usize> = (0..canonical.len())
        .filter(|&i| {
            let m = canonical.means[i];
            opaque(i) && m[0].abs() < 0.45 && (m[1] * m[1] + m[2] * m[2]).sqrt() < 0.45
        })
        .collect();
    let fixed: Vec<usize> = (0..canonical.len())
        .filter(|&i| {
            let m = canonical.means[i];
            opaque(i) && (m[2].abs() > 0.6 || (m[0].abs() > 0.4 && m[1].abs() > 0.5))
        })
        .collect();
    assert!(
        !moving.is_empty() && !fixed.is_empty(),
        "{} / {}",
        moving.len(),
        fixed.len()
    );
    let mean = |rows: &[usize]| rows.iter().map(|&i| travel(i)).sum::<f32>() / rows.len() as f32;
    let (m, s) = (mean(&moving), mean(&fixed));
    eprintln!(
        "moving {} travel {m}, static {} travel {s}",
        moving.len(),
        fixed.len()
    );
    assert!(
        (m - TRAVEL).abs() < 0.3 * TRAVEL,
        "moving part's learned travel {m}, ground truth {TRAVEL}"
    );
    assert!(s.abs() < 0.2 * TRAVEL, "static part's learned travel {s}");
}
