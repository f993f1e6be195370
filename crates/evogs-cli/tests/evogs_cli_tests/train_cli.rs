//! `evogs train`, `eval`, `render --run` and `export` end to end through the binary on a tiny
//! dynamic scene, and one-line errors naming the file for bad input.

use crate::common;
use crate::support;

use std::path::Path;
use support::{evogs, json, ok, one_line_error, rigid_scene, s, stderr, train_tiny};

#[test]
fn trains_evaluates_renders_and_exports_a_tiny_scene() {
    let dir = tempfile::tempdir().unwrap();
    // A small synthetic scene from the synth module (rigid motion, 16 training frames, 32×32).
    let data = rigid_scene(dir.path(), 32, 16);
    let run = dir.path().join("run");

    // An untrained run (0 optimiser steps: one iteration, which never steps) is the floor.
    let untrained = dir.path().join("untrained");
    let o = train_tiny(&data, &untrained, &["--iterations", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = evogs(&["eval", "--run", s(&untrained), "--split", "test"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let floor = json(&untrained.join("eval_test.json"))["mean_psnr"]
        .as_f64()
        .unwrap();

    let o = train_tiny(&data, &run, &["--seed", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("trained 300 iterations"), "{out}");
    assert!(out.contains("rasterizer backward"), "{out}");
    // Not a terminal: plain progress lines instead of a bar.
    assert!(stderr(&o).contains("iteration 300/300"), "{}", stderr(&o));
    // The detected dataset layout is said.
    assert!(out.contains("dataset: dnerf: 16 train"), "{out}");
    for f in [
        "config.json",
        "checkpoint.safetensors",
        "canonical.ply",
        "deform.safetensors",
        "train_metrics.json",
    ] {
        assert!(run.join(f).is_file(), "{f} missing");
    }

    let o = evogs(&["eval", "--run", s(&run), "--split", "test"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = json(&run.join("eval_test.json"));
    let psnr = report["mean_psnr"].as_f64().unwrap();
    // Measured: untrained 7.5 dB, trained 16.5 dB.
    assert!(
        psnr > floor + 5.0 && psnr > 14.0,
        "trained {psnr} dB vs untrained {floor} dB"
    );
    assert_eq!(report["images"].as_array().unwrap().len(), 3);
    assert!(report["temporal"]["jitter"].as_f64().unwrap().is_finite());
    assert!(run.join("eval_test.md").is_file());
    assert!(run.join("renders/test/0000.png").is_file());

    // Export at t = 0.5 and read it back with the io reader.
    let ply = dir.path().join("frame.ply");
    let o = evogs(&[
        "export",
        "--run",
        s(&run),
        "--time",
        "0.5",
        "--out",
        s(&ply),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let loaded = evogs_io::read_ply(&ply).unwrap();
    let canonical = evogs_io::read_ply(&run.join("canonical.ply")).unwrap();
    assert_eq!(loaded.gaussians.len(), canonical.gaussians.len());
    assert_eq!(loaded.gaussians.sh, canonical.gaussians.sh);
    assert_ne!(loaded.gaussians.means, canonical.gaussians.means);

    // Render one image and a sweep from a nerfies camera.
    let cam = dir.path().join("cam.json");
    support::write_small_camera(&cam);
    let img = dir.path().join("t.png");
    let o = evogs(&[
        "render",
        "--run",
        s(&run),
        "--camera",
        s(&cam),
        "--time",
        "0.25",
        "--out",
        s(&img),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(image::image_dimensions(&img).unwrap(), (24, 20));
    let sweep = dir.path().join("sweep");
    let o = evogs(&[
        "render",
        "--run",
        s(&run),
        "--camera",
        s(&cam),
        "--sweep",
        "3",
        "--out",
        s(&sweep),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(sweep.join("frame_0002.png").is_file());
    assert_eq!(
        image::image_dimensions(sweep.join("strip.png")).unwrap(),
        (72, 20)
    );
    // Beyond the training range: accepted (the network's extrapolation); non-finite: refused.
    let beyond = dir.path().join("beyond.png");
    let o = evogs(&[
        "render",
        "--run",
        s(&run),
        "--camera",
        s(&cam),
        "--time",
        "1.5",
        "--out",
        s(&beyond),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(image::image_dimensions(&beyond).unwrap(), (24, 20));
    let o = evogs(&[
        "render",
        "--run",
        s(&run),
        "--camera",
        s(&cam),
        "--time",
        "inf",
        "--out",
        s(&img),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("not a finite number"), "{}", stderr(&o));
}

#[test]
fn bad_input_gives_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let train = |data: &Path, out: &Path| train_tiny(data, out, &["--iterations", "2"]);

    // A missing image.
    let broken = dir.path().join("missing");
    copy_dir(&data, &broken);
    std::fs::remove_file(broken.join("train/r_003.png")).unwrap();
    let e = one_line_error(&train(&broken, &dir.path().join("o1")));
    assert!(
        e.contains("transforms_train.json") && e.contains("r_003"),
        "{e}"
    );

    // Malformed JSON.
    let bad_json = dir.path().join("json");
    copy_dir(&data, &bad_json);
    std::fs::write(bad_json.join("transforms_train.json"), "{\"frames\": [").unwrap();
    let e = one_line_error(&train(&bad_json, &dir.path().join("o2")));
    assert!(
        e.contains("transforms_train.json") && e.contains("JSON"),
        "{e}"
    );

    // An image of the wrong size.
    let wrong = dir.path().join("wrong");
    copy_dir(&data, &wrong);
    evogs_io::save_png(
        &wrong.join("train/r_005.png"),
        &evogs_io::ImageRgb::filled(20, 12, [0.5; 3]),
    )
    .unwrap();
    let e = one_line_error(&train(&wrong, &dir.path().join("o3")));
    assert!(e.contains("r_005.png"), "{e}");

    // An empty split.
    let empty = dir.path().join("empty");
    copy_dir(&data, &empty);
    std::fs::write(
        empty.join("transforms_train.json"),
        "{\"camera_angle_x\": 0.7, \"frames\": []}",
    )
    .unwrap();
    let e = one_line_error(&train(&empty, &dir.path().join("o4")));
    assert!(
        e.contains("transforms_train.json") && e.contains("empty"),
        "{e}"
    );

    // An unwritable output folder (a file stands where the folder should be).
    let blocker = dir.path().join("blocker");
    std::fs::write(&blocker, "not a folder").unwrap();
    let e = one_line_error(&train(&data, &blocker.join("run")));
    assert!(e.contains("blocker"), "{e}");

    // Unknown method, and a run directory that is not one.
    let o = evogs(&[
        "train",
        "--data",
        s(&data),
        "--out",
        s(&dir.path().join("o5")),
        "--method",
        "evo",
    ]);
    let e = one_line_error(&o);
    assert!(e.contains("evogs") && e.contains("baseline"), "{e}");
    let e = one_line_error(&evogs(&["eval", "--run", s(&dir.path().join("nope"))]));
    assert!(e.contains("nope"), "{e}");
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

#[test]
fn a_time_budget_ends_the_schedule_and_is_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let run = dir.path().join("run");
    // Wall clock: the test's process shares the machine with the others the harness runs.
    let o = train_tiny(
        &data,
        &run,
        &[
            "--iterations",
            "60",
            "--time-budget",
            "1.5s",
            "--budget-clock",
            "wall",
        ],
    );
    let out = ok(&o);
    assert!(out.contains("budget: spent"), "{out}");
    assert!(out.contains("schedule iteration 60 of 60"), "{out}");
    let cfg = json(&run.join("config.json"));
    assert_eq!(cfg["train"]["budget"]["seconds"], 1.5);
    assert_eq!(cfg["train"]["budget"]["clock"], "wall");
    let m = json(&run.join("train_metrics.json"));
    assert_eq!(m["budget"]["schedule_iteration"], 60);
    let spent = m["budget"]["spent_seconds"].as_f64().unwrap();
    // Not a timing assertion: the run stops on its own, at the schedule's end, near its budget
    // (the pacer's own bounds are tested on made-up readings in evogs-train).
    assert!(spent > 0.0 && spent < 15.0, "{spent}");
    assert!(m["iteration"].as_u64().unwrap() >= 1);
    // A resumed finished run stays finished; the budget cannot be changed on resume.
    let o = evogs(&["train", "--out", s(&run), "--resume"]);
    assert!(ok(&o).contains("schedule iteration 60 of 60"));
    let e = one_line_error(&evogs(&[
        "train",
        "--out",
        s(&run),
        "--resume",
        "--time-budget",
        "9s",
    ]));
    assert!(e.contains("--time-budget"), "{e}");
}

#[test]
fn bad_time_budgets_are_one_line_errors_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    let out = dir.path().join("run");
    for (args, flag) in [
        (&["--time-budget", "0s"][..], "--time-budget"),
        (&["--time-budget", "-5s"], "--time-budget"),
        (&["--time-budget", "3x"], "--time-budget"),
        (
            &["--time-budget", "10s", "--budget-clock", "moon"],
            "--budget-clock",
        ),
        (&["--budget-clock", "wall"], "--time-budget"),
    ] {
        let e = one_line_error(&train_tiny(&data, &out, args));
        assert!(e.contains(flag), "{args:?}: {e}");
    }
    for command in ["bench", "ablate"] {
        let e = one_line_error(&evogs(&[
            command,
            "--data",
            s(&data),
            "--out",
            s(&out),
            "--time-budget",
            "nope",
        ]));
        assert!(e.contains("--time-budget"), "{command}: {e}");
    }
    assert!(!out.exists());
}

/// Training into a directory that holds a run is refused (naming `--resume` and `--force`) and
/// changes nothing; `--force` removes the old run's own files first (an EvoGS run's evolution
/// state, its evaluations and renders do not survive into a baseline run) and leaves the
/// user's other files.
#[test]
fn training_into_a_run_is_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 16, 8);
    let run = dir.path().join("run");
    ok(&train_tiny(
        &data,
        &run,
        &["--iterations", "60", "--method", "evogs"],
    ));
    assert!(run.join("evo_state.safetensors").is_file());
    std::fs::create_dir_all(run.join("renders/test")).unwrap();
    std::fs::write(run.join("renders/test/0000.png"), b"old").unwrap();
    std::fs::write(run.join("eval_test.json"), b"{}").unwrap();
    std::fs::write(run.join("notes.txt"), b"mine").unwrap();
    let config = std::fs::read(run.join("config.json")).unwrap();

    let e = one_line_error(&train_tiny(&data, &run, &["--iterations", "2"]));
    assert!(
        e.contains("--out already holds a run (config.json)")
            && e.contains("--resume")
            && e.contains("--force")
            && e.contains(s(&run)),
        "{e}"
    );
    assert_eq!(std::fs::read(run.join("config.json")).unwrap(), config);
    assert!(run.join("evo_state.safetensors").is_file());

    let o = train_tiny(&data, &run, &["--iterations", "2", "--force"]);
    ok(&o);
    assert!(
        stderr(&o).contains("--force: removed the previous run"),
        "{}",
        stderr(&o)
    );
    assert!(!run.join("evo_state.safetensors").exists());
    assert!(!run.join("renders").exists());
    assert!(!run.join("eval_test.json").exists());
    assert_eq!(std::fs::read(run.join("notes.txt")).unwrap(), b"mine");
    assert_eq!(
        json(&run.join("config.json"))["train"]["method"],
        "baseline"
    );

    // --force and --resume contradict each other.
    let o = evogs(&["train", "--out", s(&run), "--resume", "--force"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
}

/// A cap of no Gaussians is refused by the parser, naming the flag and the accepted range.
#[test]
fn a_zero_gaussian_cap_is_refused_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = evogs(&[
        "train",
        "--data",
        "d",
        "--out",
        s(&out),
        "--max-gaussians",
        "0",
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--max-gaussians") && e.contains("expected a whole number >= 1"),
        "{e}"
    );
    assert!(!out.exists());
}

/// A `config.json` edited out of range is refused wherever the run is read, resume included
/// (which trained on before), naming the file, the field and the range.
#[test]
fn an_out_of_range_run_config_is_refused_on_resume_and_eval() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 16, 8);
    let run = dir.path().join("run");
    ok(&train_tiny(&data, &run, &["--iterations", "2"]));
    let path = run.join("config.json");
    let mut config = json(&path);
    config["train"]["downscale"] = serde_json::json!(2.0);
    std::fs::write(&path, serde_json::to_string_pretty(&config).unwrap()).unwrap();
    for o in [
        evogs(&["train", "--out", s(&run), "--resume"]),
        evogs(&["eval", "--run", s(&run)]),
    ] {
        let e = one_line_error(&o);
        assert!(
            e.contains("config.json") && e.contains("train.downscale") && e.contains("(0, 1]"),
            "{e}"
        );
    }
}

/// Sizes have upper bounds, from a flag or from a run's `config.json` alike: refused in one
/// line naming the field, the value and the bound, before anything is allocated or written.
#[test]
fn absurd_sizes_are_refused_before_any_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 16, 8);
    let run = dir.path().join("wide");
    let e = one_line_error(&train_tiny(&data, &run, &["--net-width", "99999"]));
    assert!(
        e.contains("net.width") && e.contains("99999: must be at most 2048"),
        "{e}"
    );
    assert!(!run.join("config.json").exists());

    let run = dir.path().join("run");
    ok(&train_tiny(
        &data,
        &run,
        &["--iterations", "2", "--method", "evogs"],
    ));
    let path = run.join("config.json");
    let mut config = json(&path);
    config["train"]["evogs"]["triplane_channels"] = serde_json::json!(65536);
    std::fs::write(&path, serde_json::to_string_pretty(&config).unwrap()).unwrap();
    for o in [
        evogs(&["eval", "--run", s(&run)]),
        evogs(&["train", "--out", s(&run), "--resume"]),
    ] {
        let e = one_line_error(&o);
        assert!(
            e.contains("config.json")
                && e.contains("evogs.triplane_channels")
                && e.contains("65536"),
            "{e}"
        );
    }
}

/// Negative and fractional numbers reach the flag's parser (not "unexpected argument '-1'"),
/// which names the flag and the accepted range.
#[test]
fn bad_numbers_are_refused_naming_the_flag_and_the_range() {
    for (args, expected) in [
        (
            &["render", "--width", "-10", "--out", "x.png"][..],
            "'--width <PIXELS>': -10 is not in 1..=16384",
        ),
        (
            &["view", "--port", "-1", "run"][..],
            "'--port <PORT>': -1 is not in 0..=65535",
        ),
        (
            &["train", "--data", "d", "--out", "o", "--iterations", "-5"][..],
            "'--iterations <N>': expected a whole number >= 1",
        ),
        (
            &["train", "--data", "d", "--out", "o", "--net-width", "2.5"][..],
            "'--net-width <W>': expected a whole number >= 2",
        ),
        (
            &["ablate", "--data", "d", "--out", "o", "--seeds", "101"][..],
            "'--seeds <N>': expected a whole number in 1..=100",
        ),
    ] {
        let e = one_line_error(&evogs(args));
        assert!(e.contains(expected), "{args:?}: {e}");
    }
}
