//! `train_log.jsonl`: a line every `log_every` iterations and at the end of each process, and the
//! lines of a resumed run continue those up to its checkpoint. (Its plot is tested in
//! `evogs-experiments`.)

use crate::common;

use evogs_backbones::GainStats;
use evogs_train::train_log::read_log;
use evogs_train::{Preset, RunPaths, TrainConfig, TrainRequest, train};

fn config() -> TrainConfig {
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(60);
    c.init_points = 300;
    c.checkpoint_every = 25;
    c.log_every = 20;
    c
}

#[test]
fn log_lines_follow_the_interval_across_a_resume() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let out = dir.path().join("run");
    let request = |resume: bool, stop_after: Option<u64>| TrainRequest {
        data: data.clone(),
        out: out.clone(),
        config: config(),
        resume,
        stop_after,
        resume_backend: None,
    };
    let log = RunPaths::new(&out).train_log();
    // Stopped at 30: lines at 20 and 30 (the end of the process), checkpoint at 30.
    train(&request(false, Some(30)), &mut |_, _| {}).unwrap();
    let first = read_log(&log).unwrap();
    assert_eq!(
        first.iter().map(|l| l.iteration).collect::<Vec<_>>(),
        vec![20, 30]
    );
    let summary = train(&request(true, None), &mut |_, _| {}).unwrap();
    let lines = read_log(&log).unwrap();
    assert_eq!(
        lines.iter().map(|l| l.iteration).collect::<Vec<_>>(),
        vec![20, 30, 40, 60]
    );
    assert_eq!(lines[..2], first[..]);
    let last = lines.last().unwrap();
    assert_eq!(last.gaussians, summary.gaussians);
    for l in &lines {
        assert!(l.loss.is_finite() && l.loss > 0.0, "{l:?}");
        assert!(l.psnr.is_finite(), "{l:?}");
        assert!(l.iterations_per_second > 0.0, "{l:?}");
        assert!(l.gain.is_none(), "the baseline has no gain");
        if cfg!(target_os = "linux") {
            assert!(l.peak_rss_bytes.unwrap() > 1 << 20, "{l:?}");
        }
    }
    // Time accumulates over the two processes.
    assert!(lines.windows(2).all(|w| w[1].seconds >= w[0].seconds));
}

#[test]
fn gain_statistics_cover_every_gaussian() {
    let k = evo_state::Gains::Learned(vec![0.25, 1.0, 0.5, 0.25]);
    let s = GainStats::of(&k, 4).unwrap();
    assert_eq!((s.mean, s.min, s.max), (0.5, 0.25, 1.0));
    let u = GainStats::of(&evo_state::Gains::Uniform(0.5), 3).unwrap();
    assert_eq!((u.mean, u.min, u.max), (0.5, 0.5, 0.5));
    assert_eq!(GainStats::of(&evo_state::Gains::Observation, 0), None);
}
