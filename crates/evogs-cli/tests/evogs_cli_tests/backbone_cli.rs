//! `evogs train --backbone 4dgs` end to end through the binary on a tiny dynamic scene: it
//! trains well above the untrained floor, the run records the backbone and its weights, and
//! unsupported combinations are one-line errors.

use crate::support;

use std::path::Path;
use support::{evogs, json, rigid_scene, s, stderr, train_tiny};

#[test]
fn the_4dgs_backbone_trains_a_tiny_scene_and_is_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 32, 16);
    let train = |out: &Path, extra: &[&str]| {
        let o = train_tiny(&data, out, &[&["--backbone", "4dgs"][..], extra].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let o = evogs(&["eval", "--run", s(out), "--split", "test"]);
        assert!(o.status.success(), "{}", stderr(&o));
        json(&out.join("eval_test.json"))["mean_psnr"]
            .as_f64()
            .unwrap()
    };
    let untrained = dir.path().join("untrained");
    let floor = train(&untrained, &["--iterations", "1"]);
    let run = dir.path().join("run");
    let psnr = train(&run, &["--seed", "3"]);
    assert!(
        psnr > floor + 5.0 && psnr > 14.0,
        "trained {psnr} dB vs untrained {floor} dB"
    );
    assert_eq!(json(&run.join("config.json"))["train"]["backbone"], "4dgs");
    // The weights file holds the HexPlane and the MLPs under their names.
    let bytes = std::fs::read(run.join("deform.safetensors")).unwrap();
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    for name in [
        "hexplane",
        "trunk",
        "head_position",
        "head_rotation",
        "head_scale",
    ] {
        assert!(
            text.contains(name),
            "{name} missing from the weights header"
        );
    }
}

#[test]
fn unknown_or_unsupported_backbones_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    for (extra, want) in [
        (vec!["--backbone", "nope"], "unknown backbone `nope`"),
        (
            vec!["--backbone", "4dgs", "--method", "evogs"],
            "EvoGS(4dgs) is not implemented yet",
        ),
    ] {
        let mut a = vec![
            "train",
            "--data",
            s(dir.path()),
            "--out",
            s(&out),
            "--preset",
            "tiny",
        ];
        a.extend_from_slice(&extra);
        let o = evogs(&a);
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(e.contains(want), "{e}");
        assert_eq!(e.trim().lines().count(), 1, "{e}");
    }
}
