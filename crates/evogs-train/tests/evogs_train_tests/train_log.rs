//! `train_log.jsonl`: a line every `log_every` iterations and at the end of each process, and the
//! lines of a resumed run are those of the run made in one process. (Its plot is tested in
//! `evogs-experiments`.)

use crate::common;

use evogs_backbones::GainStats;
use evogs_train::train_log::{LogLine, read_log};
use evogs_train::{Preset, RunPaths, TrainConfig, TrainRequest, train};

fn config() -> TrainConfig {
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(60);
    c.init_points = 300;
    c.checkpoint_every = 25;
    c.log_every = 20;
    c
}

fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        if entry.file_type().unwrap().is_file() {
            std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
        }
    }
}

/// What a line says of the training (its times are each process's own).
fn figures(lines: &[LogLine]) -> Vec<(u64, u64, u64, usize)> {
    lines
        .iter()
        .map(|l| (l.iteration, l.loss.to_bits(), l.psnr.to_bits(), l.gaussians))
        .collect()
}

/// A process stopped between two lines writes an interim line; resumed, the run's lines are
/// those of the same run made in one process, bit for bit: after a stop (the checkpoint at the
/// stop) and after a kill (the last periodic checkpoint, before the stop).
#[test]
fn log_lines_follow_the_interval_across_a_resume() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let request = |out: &str, resume: bool, stop_after: Option<u64>| TrainRequest {
        data: data.clone(),
        out: dir.path().join(out),
        config: config(),
        resume,
        stop_after,
        resume_backend: None,
        resume_net_backend: None,
    };
    let log_of = |out: &str| read_log(&RunPaths::new(dir.path().join(out)).train_log()).unwrap();
    let straight_summary = train(&request("straight", false, None), &mut |_, _| {}).unwrap();
    let straight = log_of("straight");
    assert_eq!(
        straight.iter().map(|l| l.iteration).collect::<Vec<_>>(),
        vec![20, 40, 60]
    );
    // Stopped at 30: lines at 20 and 30 (the end of the process), checkpoint at 30; a copy of
    // the run as a kill at 26 leaves it (checkpoint at 25, the line at 20).
    let killed = dir.path().join("killed");
    train(&request("run", false, Some(30)), &mut |r, _| {
        if r.iteration == 26 {
            copy_dir(&dir.path().join("run"), &killed);
        }
    })
    .unwrap();
    let first = log_of("run");
    assert_eq!(
        first.iter().map(|l| l.iteration).collect::<Vec<_>>(),
        vec![20, 30]
    );
    let summary = train(&request("run", true, None), &mut |_, _| {}).unwrap();
    train(&request("killed", true, None), &mut |_, _| {}).unwrap();
    for (name, lines) in [("stopped", log_of("run")), ("killed", log_of("killed"))] {
        assert_eq!(figures(&lines), figures(&straight), "{name}");
        assert_eq!(
            lines[0], first[0],
            "{name}: the line before the stop is kept"
        );
    }
    let lines = log_of("run");
    let last = lines.last().unwrap();
    assert_eq!(last.gaussians, summary.gaussians);
    assert_eq!(summary.gaussians, straight_summary.gaussians);
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
