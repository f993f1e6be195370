//! `--resume` ends where an uninterrupted run ends, for the D-3DGS, the Grid4D (whose regulariser
//! draws random rows every step) and the SC-GS backbone.
//!
//! The runs are compared **bit for bit** (Gaussians, every Adam moment and step count,
//! statistics, network weights), and the uninterrupted run uses one thread while the interrupted
//! and resumed runs use three. Why exact: everything random in training is a function of (seed,
//! iteration), the checkpoint stores every float bit-exactly, and every parallel reduction in the
//! pipeline has a fixed grouping (the rasterizer reduces per tile in tile order, tiny-nn's
//! parameter gradients in fixed row-block groups), so a resumed run repeats the same arithmetic
//! whatever the thread count.

use crate::common;

use evogs_train::checkpoint::load_checkpoint;
use evogs_train::run::RunPaths;
use evogs_train::state::SceneState;
use evogs_train::trainer::make_backbone;
use evogs_train::{BackboneKind, Method, Preset, TrainConfig, TrainRequest, train};

fn config_of(backbone: BackboneKind) -> TrainConfig {
    config_with(backbone, Method::Baseline)
}

fn config_with(backbone: BackboneKind, method: Method) -> TrainConfig {
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(60);
    c.method = method;
    c.init_points = 400;
    c.checkpoint_every = 7;
    c.backbone = backbone;
    // SC-GS at a test's size.
    c.backbones.scgs.control_points = 24;
    c.backbones.scgs.width = 16;
    c.backbones.scgs.depth = 2;
    c
}

fn config() -> TrainConfig {
    config_of(BackboneKind::D3dgs)
}

fn final_state(root: &std::path::Path, c: &TrainConfig) -> (SceneState, Vec<f32>, u64) {
    let mut backbone = make_backbone(c).unwrap();
    let init = evogs_train::init::random_gaussians(1, 1.0, c.sh_degree, 0);
    let mut state = SceneState::new(init, backbone.as_ref(), &c.lr).unwrap();
    let meta = load_checkpoint(
        &RunPaths::new(root).checkpoint(),
        &mut state,
        backbone.as_mut(),
    )
    .unwrap();
    let weights = backbone
        .params()
        .into_iter()
        .flat_map(|(_, p)| p.to_vec_f32())
        .collect();
    (state, weights, meta.iteration)
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn resumed_run_matches_uninterrupted_run_bit_for_bit() {
    resumes_bit_for_bit(BackboneKind::D3dgs, Method::Baseline);
}

#[test]
fn resumed_grid4d_run_matches_uninterrupted_run_bit_for_bit() {
    resumes_bit_for_bit(BackboneKind::Grid4d, Method::Baseline);
}

/// SC-GS: the control points placed at the start and the ARAP partner times (drawn from the seed
/// and the time) come back from the checkpoint and the seed alone.
#[test]
fn resumed_scgs_run_matches_uninterrupted_run_bit_for_bit() {
    resumes_bit_for_bit(BackboneKind::Scgs, Method::Baseline);
}

/// EvoGS(SC-GS) with the evolution state on every Gaussian, beside the control points.
#[test]
fn resumed_evogs_scgs_run_matches_uninterrupted_run_bit_for_bit() {
    let mut c = config_with(BackboneKind::Scgs, Method::Evogs);
    c.backbones.scgs.evolution_on = evogs_backbones::EvolutionOn::Gaussians;
    resumes_config_bit_for_bit(&c);
}

/// EvoGS(SC-GS) with the evolution state on the control points, placed again after each
/// densification (their state rows follow them).
#[test]
fn resumed_evogs_scgs_run_with_the_state_on_the_control_points_matches_bit_for_bit() {
    let mut c = config_with(BackboneKind::Scgs, Method::Evogs);
    c.backbones.scgs.evolution_on = evogs_backbones::EvolutionOn::Controls;
    c.backbones.scgs.follow_densify = true;
    resumes_config_bit_for_bit(&c);
}

fn resumes_bit_for_bit(backbone: BackboneKind, method: Method) {
    resumes_config_bit_for_bit(&config_with(backbone, method));
}

fn resumes_config_bit_for_bit(c: &TrainConfig) {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    };
    let request = |out: &str, resume: bool, stop_after: Option<u64>| TrainRequest {
        data: data.clone(),
        out: dir.path().join(out),
        config: c.clone(),
        resume,
        stop_after,
        resume_backend: None,
        resume_net_backend: None,
    };
    pool(1).install(|| train(&request("straight", false, None), &mut |_, _| {}).unwrap());
    pool(3).install(|| {
        // Interrupted at 30 (between checkpoints 28 and 35: the final checkpoint of a process is
        // written when it stops), then resumed to the end.
        let half = train(&request("resumed", false, Some(30)), &mut |_, _| {}).unwrap();
        assert_eq!(half.iteration, 30);
        let mut seen = Vec::new();
        let rest = train(&request("resumed", true, None), &mut |r, _| {
            seen.push(r.iteration);
        })
        .unwrap();
        assert_eq!(seen.first(), Some(&31));
        assert_eq!(rest.iteration, 60);
        assert_eq!(rest.iterations_this_process, 30);
    });
    let (a, wa, ia) = final_state(&dir.path().join("straight"), c);
    let (b, wb, ib) = final_state(&dir.path().join("resumed"), c);
    assert_eq!((ia, ib), (60, 60));
    assert_eq!(a.len(), b.len());
    let ga = a.gaussians();
    let gb = b.gaussians();
    assert_eq!(bits(ga.means.as_flattened()), bits(gb.means.as_flattened()));
    assert_eq!(
        bits(ga.log_scales.as_flattened()),
        bits(gb.log_scales.as_flattened())
    );
    assert_eq!(
        bits(ga.rotations.as_flattened()),
        bits(gb.rotations.as_flattened())
    );
    assert_eq!(bits(&ga.opacity_logits), bits(&gb.opacity_logits));
    assert_eq!(bits(&ga.sh), bits(&gb.sh));
    assert_eq!(bits(&wa), bits(&wb));
    assert_eq!(a.active_sh(), b.active_sh());
    for (x, y) in a.adam().groups().iter().zip(b.adam().groups()) {
        assert_eq!(x.step, y.step, "{}", x.name);
        assert_eq!(bits(&x.m), bits(&y.m), "{}", x.name);
        assert_eq!(bits(&x.v), bits(&y.v), "{}", x.name);
    }
    assert_eq!(bits(&a.stats().grad_sum), bits(&b.stats().grad_sum));
    assert_eq!(a.stats().visible, b.stats().visible);
    // The run did train the network (past the warm-up) and densify.
    assert!(c.warm_up < 30);
    assert!(
        a.adam()
            .groups()
            .iter()
            .any(|g| g.name.starts_with("net.") && g.step > 0)
    );
}

#[test]
fn resume_without_checkpoint_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(
        out.join("config.json"),
        serde_json::to_string(&evogs_train::run::RunFile {
            data: dir.path().join("nowhere"),
            train: config(),
        })
        .unwrap(),
    )
    .unwrap();
    let err = train(
        &TrainRequest {
            data: dir.path().into(),
            out: out.clone(),
            config: config(),
            resume: true,
            stop_after: None,
            resume_backend: None,
            resume_net_backend: None,
        },
        &mut |_, _| {},
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("nowhere") || err.contains("checkpoint"),
        "{err}"
    );
}
