//! `config.json` files written by an older evogs (main at 6068508, before the settings became the
//! libraries' own types) still load, give the settings the same flags give today (with
//! `--max-screen-radius 20`: the screen-size prune was always on then), are written back byte
//! for byte, and a run resumed from such a config keeps it. How the fixtures were made:
//! `tests/data/config-6068508/README.md`.

use std::path::{Path, PathBuf};

use clap::Parser;
use evogs_cli::train_cmd::config_from_args;
use evogs_cli::{Cli, Command};
use evogs_eval::LoadedRun;
use evogs_train::run::{RunFile, TrainRequest, train};

/// The fixtures with the flags (after `--data … --out …`) that wrote them, and
/// `--max-screen-radius 20` (see the module's doc).
const FIXTURES: [(&str, &[&str]); 3] = [
    (
        "evogs-tiny.json",
        &[
            "--method",
            "evogs",
            "--preset",
            "tiny",
            "--iterations",
            "2",
            "--seed",
            "3",
            "--max-screen-radius",
            "20",
        ],
    ),
    (
        "evogs-switches.json",
        &[
            "--method",
            "evogs",
            "--preset",
            "tiny",
            "--iterations",
            "2",
            "--seed",
            "4",
            "--gain",
            "0.5",
            "--history",
            "requery",
            "--densify",
            "trigger",
            "--buffer",
            "f16",
            "--net-precision",
            "f16",
            "--components",
            "pos,rot,scale,opacity,colour",
            "--motion-floor",
            "5e-4",
            "--grid-lr-scale",
            "3",
            "--psi-lr",
            "2e-3",
            "--background",
            "white",
            "--max-gaussians",
            "5000",
            "--memory-limit",
            "8G",
            "--checkpoint-every",
            "1",
            "--time-from",
            "name",
            "--max-screen-radius",
            "20",
        ],
    ),
    (
        "baseline-4dgs.json",
        &[
            "--method",
            "baseline",
            "--backbone",
            "4dgs",
            "--preset",
            "tiny",
            "--iterations",
            "2",
            "--downscale",
            "2",
            "--max-screen-radius",
            "20",
        ],
    ),
];

fn fixture(name: &str) -> (String, RunFile) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/config-6068508")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let run: RunFile =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (text, run)
}

fn lego() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../evogs-io/tests/data/dnerf-lego")
}

#[test]
fn old_configs_load_as_the_same_flags_give_and_are_written_back_unchanged() {
    for (name, flags) in FIXTURES {
        let (text, run) = fixture(name);
        let mut argv = vec!["evogs", "train", "--data", "d", "--out", "o"];
        argv.extend_from_slice(flags);
        let Command::Train(args) = Cli::try_parse_from(argv).unwrap().command else {
            unreachable!("parsed a train command")
        };
        let today = config_from_args(&args).unwrap();
        assert_eq!(run.train, today, "{name}");
        // The file format is unchanged: today's writer gives the same bytes.
        assert_eq!(serde_json::to_string_pretty(&run).unwrap(), text, "{name}");
    }
}

#[test]
fn a_run_resumed_from_an_old_config_keeps_its_settings() {
    for (name, _) in FIXTURES {
        let (_, old) = fixture(name);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        let mut request = TrainRequest {
            data: lego(),
            out: out.clone(),
            config: old.train.clone(),
            resume: false,
            stop_after: Some(1),
            resume_backend: None,
        };
        train(&request, &mut |_, _| {}).unwrap_or_else(|e| panic!("{name}: {e}"));
        // The interrupted run's config.json is the old file with this data directory.
        let written = std::fs::read_to_string(out.join("config.json")).unwrap();
        let as_old = RunFile {
            data: std::path::absolute(lego()).unwrap(),
            train: old.train.clone(),
        };
        assert_eq!(
            written,
            serde_json::to_string_pretty(&as_old).unwrap(),
            "{name}"
        );
        request.resume = true;
        request.stop_after = None;
        // What the request says besides `resume` is ignored: the run's config decides.
        request.config.seed += 1;
        let summary = train(&request, &mut |_, _| {}).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(summary.iteration, old.train.iterations, "{name}");
        let resumed = LoadedRun::open(&out).unwrap();
        assert_eq!(resumed.run.train, old.train, "{name}");
    }
}
