//! `evogs plot RUN` through the binary: a tiny run's `train_log.jsonl` drawn into a PNG, and
//! one-line errors naming the file for a run without a log and for a log that is not JSON lines.

use crate::support;

use support::{evogs, ok, one_line_error, rigid_scene, s, train_tiny};

#[test]
fn plots_a_tiny_runs_log_into_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let data = rigid_scene(dir.path(), 16, 4);
    let run = dir.path().join("run");
    // 300 iterations, a log line every 100: three lines.
    ok(&train_tiny(&data, &run, &["--seed", "1"]));
    let log = run.join("train_log.jsonl");
    let lines = std::fs::read_to_string(&log).unwrap().lines().count();
    assert_eq!(lines, 3);

    let out = ok(&evogs(&["plot", s(&run)]));
    let png = run.join("train_log.png");
    assert_eq!(
        out.trim(),
        format!("plotted 3 log lines; wrote {}", png.display())
    );
    let image = support::png(&png);
    assert_eq!(image.dimensions(), (900, 900));
    // Curves and axes were drawn: at least 1 % of the pixels are not the white background; the
    // loss curve (red) is in the top panel only, the PSNR curve (blue) in the middle one only.
    let drawn = image.pixels().filter(|p| p.0 != [255, 255, 255]).count();
    assert!(drawn > 900 * 900 / 100, "{drawn} pixels drawn");
    let panel_has = |panel: u32, colour: [u8; 3]| {
        (panel * 300..(panel + 1) * 300)
            .flat_map(|y| (0..900).map(move |x| (x, y)))
            .any(|(x, y)| image.get_pixel(x, y).0 == colour)
    };
    for (colour, panel) in [([255, 0, 0], 0), ([0, 0, 255], 1)] {
        for p in 0..3 {
            assert_eq!(panel_has(p, colour), p == panel, "{colour:?} in panel {p}");
        }
    }

    // --out writes elsewhere.
    let other = dir.path().join("elsewhere.png");
    ok(&evogs(&["plot", s(&run), "--out", s(&other)]));
    assert_eq!(support::png(&other), image);
}

#[test]
fn a_run_without_a_log_or_with_a_broken_one_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("train_log.jsonl");
    let e = one_line_error(&evogs(&["plot", s(dir.path())]));
    assert!(e.contains(s(&log)), "{e}");

    std::fs::write(&log, "{\"iteration\": 100, \"loss\": 0.1}\nnot json\n").unwrap();
    let e = one_line_error(&evogs(&["plot", s(dir.path())]));
    assert!(e.contains(s(&log)) && e.contains("line 1"), "{e}");

    std::fs::write(&log, "\n").unwrap();
    let e = one_line_error(&evogs(&["plot", s(dir.path())]));
    assert!(e.contains(s(&log)) && e.contains("no lines"), "{e}");
    assert!(!dir.path().join("train_log.png").exists());
}
