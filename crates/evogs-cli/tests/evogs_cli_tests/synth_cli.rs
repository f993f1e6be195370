//! `evogs synth`: help snapshot, a small run read back by the D-NeRF reader, and bad arguments.

use crate::support;

use support::{evogs, ok, synth_with};

#[test]
fn synth_help() {
    let out = evogs(&["synth", "--help"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let again = String::from_utf8(evogs(&["help", "synth"]).stdout).unwrap();
    assert_eq!(text, again);
    insta::assert_snapshot!("evogs_synth_help", text);
}

#[test]
fn synth_writes_a_readable_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("scene");
    let stdout = ok(&synth_with("jump", &out_dir, 24, 6, &["--seed", "9"]));
    assert!(
        stdout.contains("3000 Gaussians, 6/2/2 frames (train/test/val) at 24x24, effects: jump"),
        "{stdout}"
    );
    for split in evogs_io::Split::ALL {
        let frames = evogs_io::read_dnerf_split(&out_dir, split).unwrap();
        assert!(!frames.is_empty());
        assert!(frames.iter().all(|f| f.camera.width == 24));
    }
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("scene.json")).unwrap()).unwrap();
    assert_eq!(index["summary"]["effects"], serde_json::json!(["jump"]));
    assert_eq!(index["seed"], 9);
}

#[test]
fn unknown_preset_and_bad_size_are_one_line_errors() {
    let out = evogs(&["synth", "--preset", "nope", "--out", "x"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(
        err.contains("invalid value 'nope' for '--preset <NAME>'"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    let out = evogs(&["synth", "--preset", "rigid", "--out", "x", "--size", "4"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn monocular_protocol_with_noise_is_written_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("scene");
    let extra = [
        "--protocol",
        "monocular",
        "--pose-noise",
        "0.01",
        "--image-noise",
        "0.02",
    ];
    let stdout = ok(&synth_with("wave", &out_dir, 16, 5, &extra));
    assert!(
        stdout
            .contains("; protocol monocular (5 fixed-camera frames); noise: pose 0.01, image 0.02"),
        "{stdout}"
    );
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("scene.json")).unwrap()).unwrap();
    assert_eq!(index["spec"]["protocol"], "monocular");
    assert_eq!(
        index["spec"]["noise"],
        serde_json::json!({"pose": 0.01f32, "image": 0.02f32})
    );
    assert!(out_dir.join("fixed/transforms_train.json").is_file());
}

#[test]
fn bad_protocol_and_noise_levels_are_one_line_errors() {
    for (flag, value, want) in [
        (
            "--protocol",
            "nerfds",
            "invalid value 'nerfds' for '--protocol <NAME>'",
        ),
        ("--pose-noise", "-0.1", "-0.1 is outside 0..=0.5"),
        ("--pose-noise", "NaN", "NaN is outside 0..=0.5"),
        ("--image-noise", "2", "2 is outside 0..=1"),
        ("--image-noise", "loud", "`loud` is not a number"),
    ] {
        // `--flag=value`: a separate "-0.1" would be read as a flag.
        let out = evogs(&[
            "synth",
            "--preset",
            "wave",
            "--out",
            "x",
            &format!("{flag}={value}"),
        ]);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(err.contains(want), "{flag} {value}: {err}");
        assert!(err.contains(flag), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
}
