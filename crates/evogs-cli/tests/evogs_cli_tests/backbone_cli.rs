//! `evogs train --backbone 4dgs|grid4d|scgs` end to end through the binary on a tiny dynamic scene:
//! each backbone (and EvoGS(grid4d)) trains well above the untrained floor, the run records the
//! backbone and its weights and keeps it on resume, `evogs ablate --backbone grid4d` runs its
//! rows on it, and unsupported combinations are one-line errors.

use crate::support;

use std::path::Path;
use support::{evogs, json, rigid_scene, s, stderr, train_tiny};

#[test]
fn the_4dgs_backbone_and_evogs_4dgs_train_a_tiny_scene_and_are_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 32, 16);
    let hex = ["--backbone", "4dgs"];
    let floor = trained_psnr(
        &data,
        &dir.path().join("untrained"),
        &[&hex[..], &["--iterations", "1"]].concat(),
    );
    for (method, weights) in [
        (
            "baseline",
            &[
                "hexplane",
                "trunk",
                "head_position",
                "head_rotation",
                "head_scale",
            ][..],
        ),
        (
            "evogs",
            &["phi.hexplane", "phi.trunk", "phi.head_scale", "psi"][..],
        ),
    ] {
        let run = dir.path().join(method);
        let psnr = trained_psnr(
            &data,
            &run,
            &[&hex[..], &["--method", method, "--seed", "3"]].concat(),
        );
        assert!(
            psnr > floor + 5.0 && psnr > 14.0,
            "{method}: trained {psnr} dB vs untrained {floor} dB"
        );
        let config = json(&run.join("config.json"));
        assert_eq!(config["train"]["backbone"], "4dgs");
        assert_eq!(config["train"]["method"], method);
        assert_weights(&run, weights);
    }
}

/// SC-GS's control points: the baseline trains well above the untrained floor, records its
/// settings and its control points' buffers, `render --show-controls` draws them (and a d3dgs run
/// refuses the flag); EvoGS(SC-GS) trains and draws them too, with its state on every Gaussian
/// and on the control points, runs the ablation ladder both ways, and refuses opacity and colour
/// in one line.
#[test]
fn scgs_trains_a_tiny_scene_and_draws_its_control_points() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 32, 16);
    let scgs = [
        "--backbone",
        "scgs",
        "--control-points",
        "32",
        "--control-width",
        "32",
        "--control-depth",
        "3",
    ];
    let floor = trained_psnr(
        &data,
        &dir.path().join("untrained"),
        &[&scgs[..], &["--iterations", "1"]].concat(),
    );
    let run = dir.path().join("scgs");
    let psnr = trained_psnr(&data, &run, &[&scgs[..], &["--seed", "3"]].concat());
    assert!(
        psnr > floor + 5.0 && psnr > 14.0,
        "scgs: trained {psnr} dB vs untrained {floor} dB"
    );
    let config = json(&run.join("config.json"));
    assert_eq!(config["train"]["backbone"], "scgs");
    assert_eq!(config["train"]["scgs"]["control_points"], 32);
    assert_weights(
        &run,
        &[
            "controls.position",
            "controls.log_radius",
            "controls.weight_logit",
        ],
    );
    let image = dir.path().join("controls.png");
    let camera = ["--camera", "dataset:test:0"];
    let o = evogs(
        &[
            &[
                "render",
                "--run",
                s(&run),
                "--show-controls",
                "--out",
                s(&image),
            ][..],
            &camera[..],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let said = String::from_utf8_lossy(&o.stdout).to_string() + &stderr(&o);
    assert!(said.contains("of its 32 control points in view"), "{said}");
    let plain = dir.path().join("plain.png");
    let o = evogs(
        &[
            &["render", "--run", s(&run), "--out", s(&plain)][..],
            &camera[..],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(
        std::fs::read(&image).unwrap(),
        std::fs::read(&plain).unwrap()
    );
    let d3dgs = dir.path().join("d3dgs");
    let o = train_tiny(&data, &d3dgs, &["--iterations", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = evogs(
        &[
            &[
                "render",
                "--run",
                s(&d3dgs),
                "--show-controls",
                "--out",
                s(&image),
            ][..],
            &camera[..],
        ]
        .concat(),
    );
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("(d3dgs) has no control points"),
        "{}",
        stderr(&o)
    );
    // EvoGS(SC-GS) trains too, with the evolution state on every Gaussian and on the control
    // points, and draws the same kind of points.
    for rows in ["gaussians", "controls"] {
        let evo = dir.path().join(format!("evogs-{rows}"));
        let psnr = trained_psnr(
            &data,
            &evo,
            &[
                &scgs[..],
                &["--method", "evogs", "--seed", "3", "--evolution-on", rows],
            ]
            .concat(),
        );
        assert!(
            psnr > floor + 5.0 && psnr > 14.0,
            "EvoGS(scgs), state on {rows}: trained {psnr} dB vs untrained {floor} dB"
        );
        assert_eq!(
            json(&evo.join("config.json"))["train"]["scgs"]["evolution_on"],
            rows
        );
        assert_weights(&evo, &["phi.controls.position", "psi"]);
        let o = evogs(
            &[
                &[
                    "render",
                    "--run",
                    s(&evo),
                    "--show-controls",
                    "--out",
                    s(&image),
                ][..],
                &camera[..],
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        // Every ablation switch works with it: the whole ladder on SC-GS.
        let ablate = dir.path().join(format!("ablate-{rows}"));
        let o = evogs(
            &[
                &[
                    "ablate",
                    "--data",
                    s(&data),
                    "--out",
                    s(&ablate),
                    "--preset",
                    "tiny",
                    "--evolution-on",
                    rows,
                ][..],
                &["--iterations", "40"],
                &scgs[..],
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let ladder = json(&ablate.join("ablation.json"));
        assert_eq!(ladder["backbone"], "scgs");
        for row in [
            "baseline",
            "phi",
            "evo-requery",
            "evo-buffer",
            "trigger",
            "full",
            "k0",
            "k1",
            "net-f16",
            "buffer-f16",
        ] {
            let config = json(&ablate.join(row).join("config.json"));
            assert_eq!(config["train"]["backbone"], "scgs", "{row}");
            assert_eq!(config["train"]["scgs"]["control_points"], 32, "{row}");
            assert_eq!(config["train"]["scgs"]["evolution_on"], rows, "{row}");
        }
    }
    // SC-GS deforms no opacity or colour: asked for them, one line says so.
    let o = train_tiny(
        &data,
        &dir.path().join("evogs-opacity"),
        &[
            &scgs[..],
            &["--method", "evogs", "--components", "pos,opacity"],
        ]
        .concat(),
    );
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("scale only") && e.lines().count() == 1, "{e}");
}

/// Test PSNR of a tiny-preset run with `extra` flags, after `evogs eval`.
fn trained_psnr(data: &Path, out: &Path, extra: &[&str]) -> f64 {
    let o = train_tiny(data, out, extra);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = evogs(&["eval", "--run", s(out), "--split", "test"]);
    assert!(o.status.success(), "{}", stderr(&o));
    json(&out.join("eval_test.json"))["mean_psnr"]
        .as_f64()
        .unwrap()
}

fn assert_weights(run: &Path, names: &[&str]) {
    let bytes = std::fs::read(run.join("deform.safetensors")).unwrap();
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    for name in names {
        assert!(
            text.contains(name),
            "{name} missing from the weights header"
        );
    }
}

#[test]
fn grid4d_and_evogs_grid4d_train_a_tiny_scene_and_are_kept_on_resume() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 32, 16);
    let grid4d = ["--backbone", "grid4d"];
    let floor = trained_psnr(
        &data,
        &dir.path().join("untrained"),
        &[&grid4d[..], &["--iterations", "1"]].concat(),
    );
    let baseline = dir.path().join("baseline");
    let psnr = trained_psnr(&data, &baseline, &[&grid4d[..], &["--seed", "3"]].concat());
    assert!(
        psnr > floor + 5.0 && psnr > 14.0,
        "grid4d: trained {psnr} dB vs untrained {floor} dB"
    );
    assert_eq!(
        json(&baseline.join("config.json"))["train"]["backbone"],
        "grid4d"
    );
    assert_weights(
        &baseline,
        &[
            "grid_xyz",
            "grid_xyt",
            "grid_yzt",
            "grid_xzt",
            "attention",
            "temporal",
            "head_position",
        ],
    );

    // EvoGS(grid4d), stopped half-way and resumed: the resumed run is still EvoGS(grid4d).
    let evo = dir.path().join("evogs");
    let o = train_tiny(
        &data,
        &evo,
        &[
            &grid4d[..],
            &["--method", "evogs", "--seed", "3", "--stop-after", "150"],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = evogs(&["train", "--out", s(&evo), "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let config = json(&evo.join("config.json"));
    assert_eq!(config["train"]["backbone"], "grid4d");
    assert_eq!(config["train"]["method"], "evogs");
    assert_eq!(json(&evo.join("train_metrics.json"))["iteration"], 300);
    assert_weights(
        &evo,
        &["phi.grid_xyz", "phi.grid_xzt", "phi.attention", "psi"],
    );
    let o = evogs(&["eval", "--run", s(&evo), "--split", "test"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let psnr = json(&evo.join("eval_test.json"))["mean_psnr"]
        .as_f64()
        .unwrap();
    assert!(
        psnr > floor + 5.0 && psnr > 14.0,
        "EvoGS(grid4d): trained {psnr} dB vs untrained {floor} dB"
    );

    // The ablation ladder on the backbone: its rows record it.
    let ablate = dir.path().join("ablate");
    let o = evogs(&[
        "ablate",
        "--data",
        s(&data),
        "--out",
        s(&ablate),
        "--preset",
        "tiny",
        "--iterations",
        "60",
        "--rows",
        "baseline,full",
        "--backbone",
        "grid4d",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = std::fs::read_to_string(ablate.join("ablation.md")).unwrap();
    assert!(
        table.starts_with("# evogs ablate: backbone `grid4d`"),
        "{table}"
    );
    assert_eq!(json(&ablate.join("ablation.json"))["backbone"], "grid4d");
    for row in ["baseline", "full"] {
        let run = ablate.join(row);
        assert_eq!(
            json(&run.join("config.json"))["train"]["backbone"],
            "grid4d",
            "{row}"
        );
    }
}

#[test]
fn unknown_or_unsupported_backbones_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 16, 4);
    let out = dir.path().join("run");
    for (extra, want) in [
        (vec!["--backbone", "nope"], "unknown backbone `nope`"),
        (
            vec![
                "--backbone",
                "4dgs",
                "--method",
                "evogs",
                "--components",
                "pos,rot,scale,opacity",
            ],
            "EvoGS(4dgs)'s Φ has 4DGaussians' heads",
        ),
    ] {
        let mut a = vec![
            "train",
            "--data",
            s(&data),
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
