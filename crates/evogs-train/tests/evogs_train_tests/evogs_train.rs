//! `method = evogs` through the library on the tiny moving-block scene: the loss falls, the
//! evolution state stays aligned with the Gaussians through densification, nothing turns NaN,
//! the run directory holds the evolution state, and a resumed run ends where an uninterrupted
//! one ends (bit for bit in one thread, as `resume.rs` explains).

use crate::common;

use evo_state::EvoState;
use evogs_eval::LoadedRun;
use evogs_eval::render::render_at;
use evogs_io::Split;
use evogs_train::data::load_split;
use evogs_train::run::RunPaths;
use evogs_train::{Method, Preset, TrainConfig, TrainRequest, Trainer, train};

fn config(iterations: u64) -> TrainConfig {
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(iterations);
    c.method = Method::Evogs;
    c.init_points = 400;
    c
}

/// The scene's training views, loaded as `c` asks (time source, background, downscale).
fn train_views(data: &std::path::Path, c: &TrainConfig) -> evogs_train::data::SplitViews {
    load_split(
        data,
        Split::Train,
        c.time_from,
        c.background.rgb(),
        c.downscale,
    )
    .unwrap()
}

#[test]
fn evogs_training_lowers_the_loss_and_keeps_the_state_aligned() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let c = config(200);
    let views = train_views(&data, &c);
    let mut trainer = Trainer::new(c.clone(), views).unwrap();
    let mut losses = Vec::new();
    let mut densified = 0;
    let mut sizes = std::collections::BTreeSet::new();
    let mut gain = trainer.new_gain_report();
    let mut gain_steps = 0;
    while trainer.iteration() < c.iterations {
        let r = trainer.step().unwrap();
        if r.iteration > 150
            && let Some(step) = trainer.evolution_step()
        {
            gain_steps += usize::from(gain.add(step));
        }
        assert!(
            r.loss.is_finite() && r.psnr.is_finite(),
            "iteration {}",
            r.iteration
        );
        // The evolution state has one row per Gaussian after every step, densified or not.
        assert_eq!(trainer.backbone().state_rows(), Some(trainer.state().len()));
        densified += usize::from(r.densified);
        sizes.insert(r.gaussians);
        losses.push(r.loss);
    }
    assert!(densified > 0, "the run never densified");
    assert!(sizes.len() > 1, "the Gaussian count never changed");
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    let (first, last) = (mean(&losses[..20]), mean(&losses[losses.len() - 20..]));
    assert!(last < 0.8 * first, "loss {first} -> {last}");
    let g = trainer.state().gaussians();
    assert!(g.means.as_flattened().iter().all(|v| v.is_finite()));
    assert!(g.log_scales.as_flattened().iter().all(|v| v.is_finite()));
    assert!(g.opacity_logits.iter().all(|v| v.is_finite()));
    // Frames were committed into the buffer and the memory beside it: 2 × 16 frames × N rows ×
    // D = 10 × f32.
    assert_eq!(
        trainer.backbone().state_bytes(),
        2 * 16 * trainer.state().len() * 10 * 4
    );
    for (_, p) in trainer.backbone().params() {
        assert!(p.to_vec_f32().iter().all(|v| v.is_finite()));
    }
    // Evaluation at times between and beyond the frames works and never writes.
    let before = trainer.backbone().state_bytes();
    for t in [0.03, 0.5, 1.2] {
        let d = trainer.deformed_at(t).unwrap();
        assert_eq!(d.len(), trainer.state().len());
        assert!(d.means.as_flattened().iter().all(|v| v.is_finite()));
    }
    assert_eq!(trainer.backbone().state_bytes(), before);
    // K's distribution over the gain-stage steps of the last 50 iterations: moving and still
    // Gaussians split the samples, so do the frames, K lies in (0, 1), the percentiles are in
    // order, and the learned gain is not one constant.
    assert!(
        gain_steps > 0,
        "no gain-stage step in the last 50 iterations"
    );
    let s = gain.summary();
    let all = s.all.as_ref().unwrap();
    let count =
        |g: &Option<evogs_train::gain_report::GainStats>| g.as_ref().map_or(0, |g| g.samples);
    assert_eq!(count(&s.moving) + count(&s.still), all.samples);
    assert_eq!(s.per_frame.iter().map(count).sum::<u64>(), all.samples);
    assert!(all.mean > 0.0 && all.mean < 1.0, "{all:?}");
    assert!(all.percentiles.windows(2).all(|w| w[0] <= w[1]), "{all:?}");
    assert!(all.std > 0.0, "learned K is one constant: {all:?}");
    assert!(s.moving.is_some() || s.still.is_some());
}

/// A scene in a temporary directory and EvoGS settings checkpointing every 7 iterations, trained
/// on one thread so that runs compare bit for bit.
struct ResumeScene {
    dir: tempfile::TempDir,
    config: TrainConfig,
    pool: rayon::ThreadPool,
}

impl ResumeScene {
    fn new(iterations: u64) -> Self {
        let dir = tempfile::tempdir().unwrap();
        common::write_scene(&dir.path().join("scene"));
        let mut config = config(iterations);
        config.checkpoint_every = 7;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        Self { dir, config, pool }
    }

    /// Trains (or resumes) the run `out`, stopping after `stop_after` iterations if given.
    fn train(&self, out: &str, resume: bool, stop_after: Option<u64>) -> u64 {
        let request = TrainRequest {
            data: self.dir.path().join("scene"),
            out: self.dir.path().join(out),
            config: self.config.clone(),
            resume,
            stop_after,
            resume_backend: None,
            resume_net_backend: None,
        };
        let summary = self
            .pool
            .install(|| train(&request, &mut |_, _| {}))
            .unwrap();
        summary.iteration
    }

    fn run(&self, out: &str) -> RunPaths {
        RunPaths::new(self.dir.path().join(out))
    }
}

#[test]
fn evogs_run_directory_resumes_bit_for_bit_and_reloads() {
    let scene = ResumeScene::new(60);
    scene.train("straight", false, None);
    scene.train("resumed", false, Some(30));
    assert_eq!(scene.train("resumed", true, None), 60);
    let (a, b) = (scene.run("straight"), scene.run("resumed"));
    let ea = EvoState::load(&a.evo_state()).unwrap();
    let eb = EvoState::load(&b.evo_state()).unwrap();
    assert_eq!(ea, eb);
    assert!(ea.valid().iter().any(|&v| v), "no frame was committed");
    assert_eq!(
        std::fs::read(a.weights()).unwrap(),
        std::fs::read(b.weights()).unwrap()
    );
    // The run reads back with its evolution state and renders at any time.
    let mut run = LoadedRun::open(&a.root).unwrap();
    assert_eq!(run.run.train.method, Method::Evogs);
    assert_eq!(run.backbone.state_rows(), Some(run.canonical.len()));
    let g = run.deformed(0.4).unwrap();
    assert!(g.means.as_flattened().iter().all(|v| v.is_finite()));
    // Renders between training frames and beyond them (t = 1.2): deterministic, finite, and
    // read-only (the evolution state saved afterwards equals the one on disk).
    let camera = splat_raster::Camera::look_at(
        24,
        20,
        0.8,
        glam::Vec3::new(3.0, 0.5, 1.0),
        glam::Vec3::ZERO,
        glam::Vec3::Z,
    );
    let times = ea.frames().times().to_vec();
    let between = 0.5 * (times[3] + times[4]);
    assert!(times.iter().all(|&t| t != between));
    for t in [between, 1.2] {
        let a = render_at(&mut run, &camera, t).unwrap();
        let b = render_at(&mut run, &camera, t).unwrap();
        assert_eq!(a.pixels, b.pixels, "t = {t}");
        assert!(a.pixels.as_flattened().iter().all(|v| v.is_finite()));
    }
    let saved = scene.dir.path().join("after_render.safetensors");
    assert!(run.backbone.save_state(&saved).unwrap());
    assert_eq!(
        EvoState::load(&saved).unwrap(),
        ea,
        "rendering wrote to the state"
    );
    let e = render_at(&mut run, &camera, f32::NAN)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("not a finite number"), "{e}");
    // A missing evolution state is named.
    std::fs::remove_file(a.evo_state()).unwrap();
    let e = LoadedRun::open(&a.root).err().unwrap().to_string();
    assert!(e.contains("evo_state.safetensors"), "{e}");
}

/// A kill between writing the checkpoint and committing its evolution state (the checkpoint at
/// iteration 30 in place, its state still pending, the previous state beside it) and a kill
/// before a checkpoint landed (a pending state of a later iteration) both resume bit for bit.
#[test]
fn a_kill_between_checkpoint_and_evolution_state_resumes_bit_for_bit() {
    let scene = ResumeScene::new(45);
    let b = scene.run("killed");
    let older = scene.dir.path().join("older.safetensors");
    scene.train("straight", false, None);
    scene.train("killed", false, Some(21));
    std::fs::copy(b.evo_state(), &older).unwrap();
    scene.train("killed", true, Some(30));
    // No pending state is left once a checkpoint is written.
    assert!(!b.pending_evo_state(30).exists());
    assert_ne!(
        EvoState::load(&b.evo_state()).unwrap(),
        EvoState::load(&older).unwrap(),
        "the states at iterations 21 and 30 must differ for this test to mean anything"
    );
    std::fs::rename(b.evo_state(), b.pending_evo_state(30)).unwrap();
    std::fs::copy(&older, b.evo_state()).unwrap();
    std::fs::copy(&older, b.pending_evo_state(35)).unwrap();
    assert_eq!(scene.train("killed", true, None), 45);
    let a = scene.run("straight");
    assert_eq!(
        EvoState::load(&a.evo_state()).unwrap(),
        EvoState::load(&b.evo_state()).unwrap()
    );
    assert_eq!(
        std::fs::read(a.weights()).unwrap(),
        std::fs::read(b.weights()).unwrap()
    );
    assert!(!b.pending_evo_state(30).exists() && !b.pending_evo_state(35).exists());
}

#[test]
fn every_switch_combination_trains_finitely_and_stays_aligned() {
    use evogs_backbones::{DensifyPolicy, Gain, HistoryMode, Precision, Storage};
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let base = config(80);
    let views = train_views(&data, &base);
    type Edit = fn(&mut TrainConfig);
    let cases: [(&str, Edit); 6] = [
        ("requery", |c| {
            c.backbones.evogs.evo.history = HistoryMode::Requery;
        }),
        ("gain 0", |c| c.backbones.evogs.evo.gain = Gain::Fixed(0.0)),
        ("gain 1, standard densify", |c| {
            c.backbones.evogs.evo.gain = Gain::Fixed(1.0);
            c.backbones.evogs.densify = DensifyPolicy::Standard;
        }),
        ("f16 buffer and network", |c| {
            c.backbones.evogs.evo.storage = Storage::F16;
            c.backbones.evogs.net_precision = Precision::F16;
        }),
        ("position only", |c| {
            c.backbones.evogs.evo.layout = "pos".parse().unwrap();
        }),
        ("every component, opacity and colour included", |c| {
            c.backbones.evogs.evo.layout = "pos,rot,scale,opacity,colour".parse().unwrap();
        }),
    ];
    for (name, edit) in cases {
        let mut c = base.clone();
        edit(&mut c);
        let mut trainer = Trainer::new(c.clone(), views.clone()).unwrap();
        while trainer.iteration() < c.iterations {
            let r = trainer.step().unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(r.loss.is_finite(), "{name}: iteration {}", r.iteration);
            assert_eq!(
                trainer.backbone().state_rows(),
                Some(trainer.state().len()),
                "{name}"
            );
        }
        let dim = c.backbones.evogs.evo.layout.dim();
        // The per-frame memory always; the buffer beside it, in the same storage, unless the
        // history is re-queried.
        let bytes_per = match c.backbones.evogs.evo.storage {
            Storage::F32 => 4,
            Storage::F16 => 2,
        };
        let blocks = match c.backbones.evogs.evo.history {
            HistoryMode::Requery => 1,
            HistoryMode::Buffer => 2,
        };
        assert_eq!(
            trainer.backbone().state_bytes(),
            blocks * 16 * trainer.state().len() * dim * bytes_per,
            "{name}"
        );
        let g = trainer.deformed_at(0.45).unwrap();
        assert!(
            g.means.as_flattened().iter().all(|v| v.is_finite()),
            "{name}"
        );
    }
}

/// The buffers the trainer reuses across iterations (deformed Gaussians, deformation rows and
/// their gradient, the network's gradients, the rasterizer's outputs, the loss's workspace)
/// change nothing: a run that frees them before every step, so that each step allocates afresh,
/// reports the same losses and ends with the same Gaussians bit for bit, through densification
/// (which grows the buffers) and, for EvoGS, opacity and colour deformation; for both methods.
#[test]
fn reused_buffers_give_the_same_steps_as_fresh_ones_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    for method in [Method::Baseline, Method::Evogs] {
        let mut c = config(40);
        c.method = method;
        c.warm_up = 5;
        c.densify.schedule.from = 10;
        c.densify.schedule.interval = 10;
        if method == Method::Evogs {
            c.backbones.evogs.evo.layout = "pos,rot,scale,opacity,colour".parse().unwrap();
        }
        let views = train_views(&data, &c);
        let run = |fresh: bool| {
            let mut trainer = Trainer::new(c.clone(), views.clone()).unwrap();
            let mut reports = Vec::new();
            while trainer.iteration() < c.iterations {
                if fresh {
                    trainer.release_buffers();
                }
                let r = trainer.step().unwrap();
                reports.push((r.loss.to_bits(), r.psnr.to_bits(), r.gaussians));
            }
            let g = trainer.state().gaussians();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            (
                reports,
                bits(g.means.as_flattened()),
                bits(g.opacity_logits.as_slice()),
                bits(g.sh.as_slice()),
            )
        };
        let (reused, fresh) = (run(false), run(true));
        let counts: Vec<usize> = reused.0.iter().map(|r| r.2).collect();
        assert!(
            counts.first() != counts.last(),
            "{method}: densification changed the count: {counts:?}"
        );
        assert!(reused == fresh, "{method}: reused and fresh buffers differ");
    }
}
