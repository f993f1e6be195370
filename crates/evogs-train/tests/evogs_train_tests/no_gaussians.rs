//! A run whose densification prunes every Gaussian stops with a one-line error naming the
//! iteration, instead of training an empty scene for the rest of its schedule or budget (a
//! `dnerf` run compressed to 1 000 schedule iterations did: 0 Gaussians from step ~280 to its
//! 5 495th, results/backbones/README.md).

use crate::common;

use evogs_train::run::train;
use evogs_train::{Preset, TrainConfig, TrainError, TrainRequest};

#[test]
fn a_run_stops_when_densification_prunes_every_gaussian() {
    let dir = tempfile::tempdir().unwrap();
    common::write_scene(&dir.path().join("scene"));
    let mut config = TrainConfig::preset(Preset::Tiny).with_iterations(60);
    config.init_points = 200;
    // Every Gaussian starts at opacity 0.1, below this: the first densification prunes them all.
    config.densify.min_opacity = 0.99;
    let schedule = config.densify.schedule;
    let request = TrainRequest {
        data: dir.path().join("scene"),
        out: dir.path().join("run"),
        config,
        resume: false,
        stop_after: None,
        resume_backend: None,
        resume_net_backend: None,
    };
    let mut counts = Vec::new();
    let err = train(&request, &mut |r, _| {
        counts.push((r.iteration, r.gaussians));
    })
    .unwrap_err();
    let first = (1..=60).find(|&i| schedule.densifies(i)).unwrap();
    match err {
        TrainError::NoGaussians {
            iteration,
            schedule_iteration,
        } => {
            assert_eq!(iteration, first, "{counts:?}");
            assert_eq!(schedule_iteration, iteration);
        }
        other => panic!("expected NoGaussians, got {other}"),
    }
    // Every step before it still had its Gaussians; the one that pruned them was the last.
    assert!(
        counts[..counts.len() - 1].iter().all(|&(_, n)| n == 200),
        "{counts:?}"
    );
    assert_eq!(counts.last(), Some(&(first, 0)));
    let text = err.to_string();
    assert!(!text.contains('\n'), "{text}");
    assert!(text.contains(&format!("iteration {first} ")), "{text}");
}
