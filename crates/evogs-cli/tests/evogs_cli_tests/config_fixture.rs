//! `config.json` files written by older evogs (main at 6068508, before the settings became the
//! libraries' own types; main at e616b30, before `--triplane-combine`; main at 04d89b0, before
//! SC-GS's settings; main at b51c05c, before `scgs.evolution_on`; main at ee24eb9, before
//! `net_backend`; main at 22ec30d, before `scgs.placement`) still load, give the
//! settings the same flags give today (with `--max-screen-radius 20`: the screen-size prune was
//! always on then), and a run resumed from such a config keeps it. Today's format is pinned by
//! the same three runs' files written by today's evogs (`tests/data/config-current`): each old
//! file loads as its current twin and is written back as the twin's bytes, and each twin is
//! written back byte for byte. How the fixtures were made: the `README.md` of each directory of
//! `tests/data/config-*`.

use std::path::{Path, PathBuf};

use clap::Parser;
use evogs_backbones::EvolutionOn;
use evogs_cli::train_cmd::config_from_args;
use evogs_cli::{Cli, Command};
use evogs_eval::LoadedRun;
use evogs_train::run::{RunFile, TrainRequest, train};
use splat_raster::BackendChoice;

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

/// The fixtures of older evogs, oldest first (the module's doc says what each lacks).
const OLD: [&str; 6] = [
    "config-6068508",
    "config-e616b30",
    "config-04d89b0",
    "config-b51c05c",
    "config-ee24eb9",
    "config-22ec30d",
];
/// The same runs' files in today's format.
const CURRENT: &str = "config-current";

fn fixture(dir: &str, name: &str) -> (String, RunFile) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(dir)
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
fn old_configs_load_as_the_same_flags_give_and_are_written_back_in_todays_format() {
    for ((name, flags), old) in FIXTURES.into_iter().flat_map(|f| OLD.map(|old| (f, old))) {
        let (old_text, run) = fixture(old, name);
        let (current_text, current) = fixture(CURRENT, name);
        let mut argv = vec!["evogs", "train", "--data", "d", "--out", "o"];
        argv.extend_from_slice(flags);
        let Command::Train(args) = Cli::try_parse_from(argv).unwrap().command else {
            unreachable!("parsed a train command")
        };
        let today = config_from_args(&args).unwrap();
        // The settings whose meaning in a file without them differs from today's default:
        // EvoGS(SC-GS)'s state was on every Gaussian before `scgs.evolution_on` existed (a file
        // from before SC-GS itself, without `scgs`, takes SC-GS's defaults whole); every
        // network ran on the CPU before `net_backend` existed.
        let mut then = today.clone();
        let scgs_before_the_choice =
            old_text.contains(r#""scgs""#) && !old_text.contains("evolution_on");
        if scgs_before_the_choice {
            then.backbones.scgs.evolution_on = EvolutionOn::recorded_before_the_choice();
        }
        let before_net_backend = !old_text.contains("net_backend");
        if before_net_backend {
            then.net_backend = BackendChoice::Cpu;
        }
        assert_eq!(run.train, then, "{old}/{name}");
        assert_eq!(current.train, today, "{name}");
        // Today's format: an old file is written back as its current twin, byte for byte, and
        // the twin as itself. (The format changed six times since 6068508: in the order of the
        // `evogs` object's keys, evo-state's config embedded first; then `triplane_combine`;
        // then SC-GS's `scgs` object; then its `evolution_on`; then `net_backend`; then
        // `scgs.placement`, which a file without it reads as today's default.)
        let text = serde_json::to_string_pretty(&run).unwrap();
        let mut then_text = current_text.clone();
        if before_net_backend {
            then_text = then_text.replace(r#""net_backend": "auto""#, r#""net_backend": "cpu""#);
        }
        if scgs_before_the_choice {
            then_text = then_text.replace(
                r#""evolution_on": "controls""#,
                r#""evolution_on": "gaussians""#,
            );
        }
        assert_eq!(text, then_text, "{old}/{name}");
        assert_eq!(
            serde_json::to_string_pretty(&current).unwrap(),
            current_text,
            "{name}"
        );
    }
}

#[test]
fn a_run_resumed_from_an_old_config_keeps_its_settings() {
    for (name, _) in FIXTURES {
        let (_, old) = fixture(OLD[0], name);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        let mut request = TrainRequest {
            data: lego(),
            out: out.clone(),
            config: old.train.clone(),
            resume: false,
            stop_after: Some(1),
            resume_backend: None,
            resume_net_backend: None,
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
