//! The training plot of `evogs plot`: `plot_run` draws every line of a run's `train_log.jsonl`,
//! and a run without a log is refused naming the file.

use evogs_backbones::GainStats;
use evogs_experiments::train_plot::plot_run;
use evogs_train::RunPaths;
use evogs_train::train_log::LogLine;

fn line(iteration: u64, loss: f64, gaussians: usize) -> LogLine {
    LogLine {
        iteration,
        seconds: iteration as f64 * 0.5,
        loss,
        psnr: 10.0 - 10.0 * loss.log10(),
        gaussians,
        iterations_per_second: 40.0,
        peak_rss_bytes: Some(1 << 26),
        gain: (iteration > 20).then_some(GainStats {
            mean: 0.5,
            min: 0.1,
            max: 0.9,
        }),
    }
}

#[test]
fn plot_of_a_log_draws_every_line() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    std::fs::create_dir_all(&run).unwrap();
    let lines = [
        line(20, 0.30, 300),
        line(30, 0.20, 320),
        line(40, 0.15, 360),
        line(60, 0.12, 410),
    ];
    let text: String = lines
        .iter()
        .map(|l| serde_json::to_string(l).unwrap() + "\n")
        .collect();
    std::fs::write(RunPaths::new(&run).train_log(), text).unwrap();

    let png = dir.path().join("log.png");
    assert_eq!(plot_run(&run, &png).unwrap(), 4);
    let image = image::open(&png).unwrap();
    assert_eq!((image.width(), image.height()), (900, 900));
    // Something other than the white background was drawn.
    assert!(image.to_rgb8().pixels().any(|p| p.0 != [255, 255, 255]));
}

#[test]
fn plot_of_a_run_without_log_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let err = plot_run(dir.path(), &dir.path().join("x.png"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("train_log.jsonl"), "{err}");
}

#[test]
fn plot_of_an_empty_log_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(RunPaths::new(dir.path()).train_log(), "").unwrap();
    let err = plot_run(dir.path(), &dir.path().join("x.png"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("train_log.jsonl") && err.contains("no lines to plot"),
        "{err}"
    );
}
