//! `evogs ablate` end to end through the binary on a tiny synthetic scene with a subset of rows:
//! the table, the JSON and the PNG exist, the table and JSON hold exactly those rows, the PNG
//! decodes; and bad `--rows` gives a one-line error naming the setting.

use crate::support;

use support::{ablate_tiny, evogs, ok, s, stderr, synth, synth_with};

#[test]
fn ablates_three_rows_of_a_tiny_scene() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    synth("jump", &data, 32, 12);
    let out = dir.path().join("ablation");
    let o = ablate_tiny(&data, &out, 30, &["--rows", "phi,baseline,k0.5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let log = stderr(&o);
    for name in ["baseline", "phi", "k0.5"] {
        assert!(log.contains(&format!("{name}: started")), "{log}");
        assert!(log.contains(&format!("{name}: finished")), "{log}");
        assert!(out.join(name).join("config.json").is_file(), "{name}");
    }

    let table = std::fs::read_to_string(out.join("ablation.md")).unwrap();
    let names: Vec<&str> = table
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| row") && !l.starts_with("| ---"))
        .map(|l| l.split('|').nth(1).unwrap().trim())
        .collect();
    assert_eq!(names, ["baseline", "phi", "k0.5"], "{table}");
    assert!(table.contains("evolution=off"), "{table}");
    assert!(table.contains("gain=0.5"), "{table}");
    assert!(table.contains("30 iterations per row, seed 3"), "{table}");
    assert!(table.contains("| SSIM | lpips_alex |"), "{table}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("ablation.json")).unwrap()).unwrap();
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    for row in rows {
        assert!(row["psnr"].as_f64().unwrap().is_finite(), "{row}");
        assert!(row["seconds"].as_f64().unwrap() > 0.0, "{row}");
        assert!(row["gaussians"].as_u64().unwrap() > 0, "{row}");
        assert!(row["lpips_alex"].as_f64().unwrap() > 0.0, "{row}");
    }
    // Only evolution keeps a state (buffer and memory): not the baseline, not Φ alone.
    assert_eq!(rows[0]["state_bytes"], 0);
    assert_eq!(rows[1]["state_bytes"], 0);
    assert!(rows[2]["state_bytes"].as_u64().unwrap() > 0);

    let png = image::open(out.join("ablation.png")).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (800, 600));
    // Not a blank image: the axes and points are drawn.
    assert!(png.pixels().any(|p| p.0 != [255, 255, 255]));
}

#[test]
fn unknown_row_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let o = evogs(&[
        "ablate",
        "--data",
        s(dir.path()),
        "--out",
        s(&dir.path().join("o")),
        "--rows",
        "baseline,bogus",
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(e.contains("rows") && e.contains("bogus"), "{e}");
}

#[test]
fn seeds_run_every_row_per_seed_on_a_monocular_scene_and_report_mean_and_std() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    ok(&synth_with(
        "wave",
        &data,
        24,
        8,
        &["--protocol", "monocular"],
    ));
    let out = dir.path().join("ablation");
    let o = ablate_tiny(&data, &out, 20, &["--seeds", "2", "--rows", "k0,phi"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let log = stderr(&o);
    for name in ["phi", "k0"] {
        for seed in [3, 4] {
            assert!(
                log.contains(&format!("{name} seed {seed}: finished")),
                "{log}"
            );
            let run = out.join(name).join(format!("seed{seed}"));
            let config: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).unwrap())
                    .unwrap();
            assert_eq!(config["train"]["seed"], seed, "{config}");
        }
    }
    let table = std::fs::read_to_string(out.join("ablation.md")).unwrap();
    assert!(
        table.contains("20 iterations per row, seeds 3, 4 (mean ± sample std over seeds)"),
        "{table}"
    );
    let phi = table.lines().find(|l| l.starts_with("| phi ")).unwrap();
    assert!(phi.contains(" | 2 | ") && phi.contains(" ± "), "{phi}");
    // K = 0 is a prior-only row with standard densification, and its mean K is 0.
    let k0 = table.lines().find(|l| l.starts_with("| k0 ")).unwrap();
    assert!(k0.contains("densify=standard gain=0 "), "{k0}");
    assert!(k0.contains("| 0.000 ± 0.000 |"), "{k0}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("ablation.json")).unwrap()).unwrap();
    assert_eq!(json["seeds"], serde_json::json!([3, 4]));
    for row in json["rows"].as_array().unwrap() {
        let runs = row["seeds"].as_array().unwrap();
        assert_eq!(runs.len(), 2, "{row}");
        let mean = (runs[0]["psnr"].as_f64().unwrap() + runs[1]["psnr"].as_f64().unwrap()) / 2.0;
        assert!((row["psnr"].as_f64().unwrap() - mean).abs() < 1e-9, "{row}");
        assert!(row["std"]["psnr"].as_f64().unwrap() >= 0.0, "{row}");
    }
}
