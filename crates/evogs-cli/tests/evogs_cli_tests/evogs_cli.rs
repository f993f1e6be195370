//! `evogs train --method evogs` (with non-default switches), then `eval`, `render --run`,
//! `export` and `--resume` on the run, through the binary on the tiny moving-block scene.

use crate::common;
use crate::support;

use support::{evogs, ok, s};

#[test]
fn evogs_run_trains_evaluates_renders_exports_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let run = dir.path().join("run");
    ok(&evogs(&[
        "train",
        "--data",
        s(&data),
        "--out",
        s(&run),
        "--preset",
        "tiny",
        "--iterations",
        "120",
        "--method",
        "evogs",
        "--gain",
        "0.5",
        "--buffer",
        "f16",
        "--densify",
        "trigger",
        "--stop-after",
        "80",
    ]));
    for f in [
        "config.json",
        "checkpoint.safetensors",
        "deform.safetensors",
        "evo_state.safetensors",
    ] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    let config: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).unwrap()).unwrap();
    assert_eq!(config["train"]["method"], "evogs");
    assert_eq!(config["train"]["evogs"]["buffer"], "f16");
    assert_eq!(config["train"]["evogs"]["densify"], "trigger");
    assert_eq!(config["train"]["evogs"]["gain"]["fixed"], 0.5);
    ok(&evogs(&["train", "--out", s(&run), "--resume"]));
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("train_metrics.json")).unwrap())
            .unwrap();
    assert_eq!(metrics["iteration"], 120);

    let o = evogs(&["eval", "--run", s(&run), "--split", "test"]);
    ok(&o);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("eval_test.json")).unwrap())
            .unwrap();
    assert!(report["mean_psnr"].as_f64().unwrap() > 15.0, "{report}");
    // Progress: off a terminal, a line every tenth of the views, the last one at the end.
    let views = report["images"].as_array().unwrap().len();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(&format!("view {views}/{views}")), "{err}");
    // LPIPS: AlexNet by default (scripts/test installs the weights), VGG16 with the flag.
    let lpips_alex = report["mean_lpips_alex"].as_f64().unwrap();
    assert!(lpips_alex > 0.0 && lpips_alex < 1.0, "{report}");
    assert!(report.get("mean_lpips_vgg").is_none(), "{report}");
    ok(&evogs(&[
        "eval",
        "--run",
        s(&run),
        "--split",
        "test",
        "--lpips-vgg",
    ]));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("eval_test.json")).unwrap())
            .unwrap();
    assert_eq!(report["mean_lpips_alex"].as_f64().unwrap(), lpips_alex);
    assert!(report["mean_lpips_vgg"].as_f64().unwrap() > 0.0, "{report}");
    // Without weights: one line naming the install command, the other metrics still reported.
    let empty = dir.path().join("no-weights");
    let o = evogs(&[
        "eval",
        "--run",
        s(&run),
        "--split",
        "test",
        "--lpips-weights",
        s(&empty),
    ]);
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = err.lines().filter(|l| l.contains("LPIPS")).collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(
        lines[0].contains("scripts/lpips-weights") && lines[0].contains("no-weights"),
        "{err}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("eval_test.json")).unwrap())
            .unwrap();
    assert!(report["mean_psnr"].as_f64().unwrap() > 15.0, "{report}");
    assert!(report.get("mean_lpips_alex").is_none(), "{report}");
    assert_eq!(
        report["lpips_missing"].as_array().unwrap().len(),
        1,
        "{report}"
    );

    let ply = dir.path().join("frame.ply");
    ok(&evogs(&[
        "export",
        "--run",
        s(&run),
        "--time",
        "0.6",
        "--out",
        s(&ply),
    ]));
    let loaded = evogs_io::read_ply(&ply).unwrap();
    let canonical = evogs_io::read_ply(&run.join("canonical.ply")).unwrap();
    assert_eq!(loaded.gaussians.len(), canonical.gaussians.len());
    assert_ne!(loaded.gaussians.means, canonical.gaussians.means);

    let cam = dir.path().join("cam.json");
    support::write_small_camera(&cam);
    let img = dir.path().join("t.png");
    // Times between training frames (the CLI takes times in [0, 1]).
    for t in ["0.41", "0.99"] {
        ok(&evogs(&[
            "render",
            "--run",
            s(&run),
            "--camera",
            s(&cam),
            "--time",
            t,
            "--out",
            s(&img),
        ]));
        assert_eq!(image::image_dimensions(&img).unwrap(), (24, 20));
    }
}
