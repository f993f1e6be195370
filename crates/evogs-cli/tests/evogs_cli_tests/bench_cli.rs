//! `evogs bench` end to end through the binary on two tiny synthetic scenes and both methods:
//! the table holds one row per scene × method with both splits, the JSON holds the runs with
//! their curves and peak memory, the plot and one picture per scene decode; bad input gives a
//! one-line error naming the setting.

use crate::support;

use support::{evogs, s, stderr, synth};

#[test]
fn benches_two_scenes_with_both_methods() {
    let dir = tempfile::tempdir().unwrap();
    // `dnerf-` is dropped from the scene's name, as for the real D-NeRF folders.
    let (a, b) = (dir.path().join("dnerf-jump"), dir.path().join("wave"));
    synth("jump", &a, 32, 8);
    synth("wave", &b, 32, 8);
    let out = dir.path().join("bench");
    let data = format!("{},{}", s(&a), s(&b));
    let o = evogs(&[
        "bench",
        "--data",
        &data,
        "--out",
        s(&out),
        "--preset",
        "tiny",
        "--iterations",
        "20",
        "--eval-every",
        "10",
        "--seed",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let log = stderr(&o);
    for scene in ["jump", "wave"] {
        for method in ["baseline", "evogs"] {
            assert!(log.contains(&format!("{scene} {method}: started")), "{log}");
            assert!(
                log.contains(&format!("{scene} {method}: finished")),
                "{log}"
            );
            assert!(
                out.join(scene)
                    .join(method)
                    .join("eval_test.json")
                    .is_file()
            );
            assert!(out.join(scene).join(method).join("eval_val.json").is_file());
        }
        let picture = image::open(out.join(format!("{scene}.png"))).unwrap();
        // Ground truth and two methods side by side, three times down.
        assert!(picture.width() > 2 * picture.height() / 3, "{picture:?}");
    }
    let table = std::fs::read_to_string(out.join("bench.md")).unwrap();
    let rows: Vec<Vec<&str>> = table
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| scene") && !l.starts_with("| ---"))
        .map(|l| l.split('|').map(str::trim).collect())
        .collect();
    let keys: Vec<(&str, &str, &str)> = rows.iter().map(|r| (r[1], r[2], r[3])).collect();
    assert_eq!(
        keys,
        [
            ("jump", "baseline", "test"),
            ("jump", "evogs", "test"),
            ("wave", "baseline", "test"),
            ("wave", "evogs", "test")
        ],
        "{table}"
    );
    assert!(
        table.contains("preset `tiny`, 20 iterations, seed 2"),
        "{table}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bench.json")).unwrap()).unwrap();
    let runs = json["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 4);
    for run in runs {
        let curve = run["curve"].as_array().unwrap();
        let iterations: Vec<u64> = curve
            .iter()
            .map(|p| p["iteration"].as_u64().unwrap())
            .collect();
        assert_eq!(iterations, [10, 20], "{run}");
        assert!(
            curve
                .iter()
                .all(|p| p["psnr"].as_f64().unwrap().is_finite())
        );
        assert_eq!(run["non_finite"].as_u64(), Some(0));
        assert_eq!(run["scores"].as_array().unwrap().len(), 2);
    }
    assert!(!json["published"].as_array().unwrap().is_empty());
    image::open(out.join("bench.png")).unwrap();
}

#[test]
fn unknown_method_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let o = evogs(&[
        "bench",
        "--data",
        s(dir.path()),
        "--out",
        s(&dir.path().join("out")),
        "--methods",
        "baseline,evo",
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(e.contains("method") && e.contains("evo"), "{e}");
}

/// The numbers of a bench's runs that do not depend on the machine: every run's scene, method,
/// iterations, Gaussians and scores, and its curve without the times.
fn machine_free(bench: &std::path::Path) -> Vec<serde_json::Value> {
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(bench.join("bench.json")).unwrap()).unwrap();
    json["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            let curve: Vec<_> = r["curve"]
                .as_array()
                .unwrap()
                .iter()
                .map(|p| (p["iteration"].clone(), p["psnr"].clone()))
                .collect();
            serde_json::json!([
                r["scene"],
                r["method"],
                r["iterations"],
                r["gaussians"],
                r["scores"],
                curve
            ])
        })
        .collect()
}

#[test]
fn jobs_train_the_runs_apart_into_the_same_table() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("jump"), dir.path().join("wave"));
    synth("jump", &a, 32, 8);
    synth("wave", &b, 32, 8);
    let data = format!("{},{}", s(&a), s(&b));
    let bench = |out: &std::path::Path, jobs: &str| {
        let o = evogs(&[
            "bench",
            "--data",
            &data,
            "--out",
            s(out),
            "--preset",
            "tiny",
            "--iterations",
            "20",
            "--eval-every",
            "10",
            "--seed",
            "3",
            "--jobs",
            jobs,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let (one, two) = (dir.path().join("one"), dir.path().join("two"));
    bench(&one, "1");
    let log = bench(&two, "3");
    for scene in ["jump", "wave"] {
        for method in ["baseline", "evogs"] {
            assert!(
                log.contains(&format!("{scene} {method}: finished")),
                "{log}"
            );
            assert!(
                two.join(scene)
                    .join(method)
                    .join("bench_run.json")
                    .is_file()
            );
        }
        image::open(two.join(format!("{scene}.png"))).unwrap();
    }
    image::open(two.join("bench.png")).unwrap();
    // Training is bit-identical for any thread count, so the parts give the same numbers in
    // the same order.
    let (seq, par) = (machine_free(&one), machine_free(&two));
    assert_eq!(seq.len(), 4);
    assert_eq!(seq, par);
}

#[test]
fn a_failed_part_fails_the_bench_naming_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("jump");
    synth("jump", &a, 32, 8);
    let missing = dir.path().join("nosuch");
    let data = format!("{},{}", s(&a), s(&missing));
    let o = evogs(&[
        "bench",
        "--data",
        &data,
        "--out",
        s(&dir.path().join("out")),
        "--preset",
        "tiny",
        "--iterations",
        "10",
        "--methods",
        "baseline",
        "--jobs",
        "2",
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("nosuch"), "{e}");
    assert!(e.contains("failed runs: nosuch baseline"), "{e}");
    assert!(!dir.path().join("out").join("bench.md").exists(), "{e}");
}

/// A budget far too short for the schedule asked for: the schedule falls behind, the bench says
/// so in a warning naming the flag that fixes it, and the table marks the row.
#[test]
fn a_schedule_that_lags_its_budget_is_warned_about_and_marked() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("jump");
    synth("jump", &data, 32, 8);
    let out = dir.path().join("bench");
    let o = evogs(&[
        "bench",
        "--data",
        s(&data),
        "--out",
        s(&out),
        "--methods",
        "baseline",
        "--preset",
        "tiny",
        "--iterations",
        "1000000",
        "--time-budget",
        "1s",
        "--eval-every",
        "1000000",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let log = stderr(&o);
    let warning = log
        .lines()
        .find(|l| l.contains("fell behind the time budget"))
        .unwrap_or_else(|| panic!("no lag warning in {log}"));
    assert!(
        warning.starts_with("warning: jump baseline:") && warning.contains("--iterations near"),
        "{warning}"
    );
    let table = std::fs::read_to_string(out.join("bench.md")).unwrap();
    assert!(table.contains(" (lagged "), "{table}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bench.json")).unwrap()).unwrap();
    assert!(json["runs"][0]["schedule_lagged"].as_u64().unwrap() > 0);
}
