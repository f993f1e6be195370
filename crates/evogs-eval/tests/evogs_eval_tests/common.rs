//! What the tests share: evogs-train's tiny scene and a short run trained on it.

use std::path::Path;

use evogs_eval::LoadedRun;
use evogs_train::{Preset, TrainConfig, TrainRequest, train};

// evogs-train's tiny scene, shared with its tests and evogs-cli's (included by path).
#[path = "../../../evogs-train/tests/common/mod.rs"]
mod scene;

/// Trains 40 iterations of the tiny preset (300 initial points) on evogs-train's tiny scene,
/// written to `dir/scene`, into `dir/run`, and reads the run back.
pub fn tiny_run(dir: &Path) -> LoadedRun {
    let data = dir.join("scene");
    scene::write_scene(&data);
    let out = dir.join("run");
    let mut config = TrainConfig::preset(Preset::Tiny).with_iterations(40);
    config.init_points = 300;
    train(
        &TrainRequest {
            data,
            out: out.clone(),
            config,
            resume: false,
            stop_after: None,
            resume_backend: None,
            resume_net_backend: None,
        },
        &mut |_, _| {},
    )
    .unwrap();
    LoadedRun::open(&out).unwrap()
}
