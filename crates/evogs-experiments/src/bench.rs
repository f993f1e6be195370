//! The D-NeRF benchmark (issue Q): trains every scene × method of a request with one config,
//! evaluates each run on its test and val splits, and writes one table with the published
//! figures beside ours ([`table`]: `bench.md`, and `bench.json`), a PSNR-against-training-time
//! plot (`bench.png`, [`crate::bench_plot`]) and a picture per scene (`<scene>.png`: ground truth
//! | each method, at the earliest, middle and latest time of the scene's headline split).
//! A run's record ([`BenchRun`]) and the published figures ([`PUBLISHED`], [`published_for`]) are
//! defined in the module below this one and the plot (`bench_data`) and re-exported here.
//!
//! - The headline split is the one the literature reports ([`headline_split`]): lego's val split
//!   (its test split does not match the training motion; D-3DGS reports val), the test split of
//!   every other scene. Both splits are evaluated and tabled for every scene.
//! - The curve: every `eval_every` iterations the run is rendered on its headline split from
//!   inside the training loop; the time axis is training time only (the evaluations are timed
//!   and subtracted). It is a report, never used to choose settings.
//! - Peak memory: the process's peak resident set (`VmHWM`), reset before each run where Linux
//!   allows (`/proc/self/clear_refs`), read after training; `None` elsewhere.
//! - Non-finite values: the trained canonical Gaussians are checked; a NaN or Inf during training
//!   already stops the run with an error naming the Gaussian.
//! - Each finished run also writes its row as [`RUN_RECORD`] in its run directory, so that runs
//!   trained apart (`evogs bench --jobs`, one process per run: each its own peak memory and CPU
//!   clock) are gathered into one table by [`read_run_record`] and [`write_summaries`].
//!
//! What it is not: a timing harness (times are wall-clock on whatever else runs on the machine;
//! the table says so) or a place that chooses settings.

use std::path::{Path, PathBuf};
use std::time::Instant;

use evogs_io::{ImageRgb, Split};

pub use crate::bench_data::{
    BenchRun, CurvePoint, PUBLISHED, PUBLISHED_SCGS, Published, SplitScore, published_for,
    published_scgs_for,
};
use crate::bench_plot;
use crate::error::ExperimentError;
use crate::write::{write_bytes, write_json, write_png};
use evogs_eval::LoadedRun;
use evogs_eval::eval::{EvalLpips, evaluate, non_finite_gaussians};
use evogs_metrics::{ImageSize, psnr};
use evogs_train::config::{Method, TrainConfig};
use evogs_train::data::{SplitViews, load_split};
use evogs_train::run::{TrainRequest, train};

/// One scene: a name (table rows, file names) and its dataset directory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BenchScene {
    /// Short name, e.g. `lego`.
    pub name: String,
    /// Dataset directory.
    pub data: PathBuf,
}

impl BenchScene {
    /// The scene in `dir`, named by the directory's last component without a `dnerf-` prefix
    /// (`…/dnerf-lego` is `lego`).
    pub fn from_dir(dir: &Path) -> Self {
        let base = dir
            .file_name()
            .map_or_else(|| "scene".to_string(), |n| n.to_string_lossy().into_owned());
        let name = base.strip_prefix("dnerf-").unwrap_or(&base).to_string();
        Self {
            name,
            data: dir.to_path_buf(),
        }
    }
}

/// The split the literature reports for a D-NeRF scene: `val` for lego (its test split shows
/// the shovel at other angles than its training frames; D-3DGS evaluates on val), `test`
/// otherwise.
pub fn headline_split(scene: &str) -> Split {
    if scene.contains("lego") {
        Split::Val
    } else {
        Split::Test
    }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BenchRequest {
    /// Scenes, in table order.
    pub scenes: Vec<BenchScene>,
    /// Methods, in table order.
    pub methods: Vec<Method>,
    /// Settings of every run (each run sets `method`).
    pub config: TrainConfig,
    /// Curve points every this many iterations (and at the end).
    pub eval_every: u64,
    /// Output directory: `<scene>/<method>/` run directories, the table, the plot, the pictures.
    pub out: PathBuf,
}

/// Progress of [`run_bench`].
#[derive(Debug)]
pub enum BenchProgress<'a> {
    /// A run starts.
    Started {
        /// Scene name.
        scene: &'a str,
        /// Method.
        method: Method,
    },
    /// A training step of the current run (every step, for a progress bar).
    Step {
        /// The schedule iteration the step reached.
        schedule_iteration: u64,
        /// The schedule's length.
        schedule: u64,
    },
    /// A curve point of the current run.
    Point {
        /// Scene name.
        scene: &'a str,
        /// Method.
        method: Method,
        /// The point.
        point: CurvePoint,
    },
    /// A run is done.
    Finished {
        /// Its result.
        run: &'a BenchRun,
    },
}

/// Peak resident set of this process in bytes (`VmHWM`), on Linux.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Resets the peak resident set to the current one (Linux `clear_refs` 5); returns whether it
/// could.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Mean PSNR of the trainer's renders of `views` (colours clamped to [0, 1], as evaluation).
fn mean_psnr(
    trainer: &mut evogs_train::Trainer,
    views: &SplitViews,
) -> Result<f64, ExperimentError> {
    let mut sum = 0.0;
    for v in &views.views {
        let colour: Vec<[f32; 3]> = trainer
            .render(&v.camera, v.time)?
            .into_iter()
            .map(|c| c.map(|x| x.clamp(0.0, 1.0)))
            .collect();
        let size = ImageSize::new(v.image.width as usize, v.image.height as usize);
        sum += psnr(size, &colour, &v.image.pixels)?;
    }
    Ok(sum / views.views.len().max(1) as f64)
}

/// Trains and evaluates one scene × method into `out` (its run directory).
fn bench_one(
    scene: &BenchScene,
    config: TrainConfig,
    eval_every: u64,
    out: &Path,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(BenchProgress<'_>),
) -> Result<BenchRun, ExperimentError> {
    let method = config.method;
    let schedule = config.iterations;
    let headline = headline_split(&scene.name);
    let curve_views = load_split(
        &scene.data,
        headline,
        config.time_from,
        config.background.rgb(),
        config.downscale,
    )?;
    let resolution = curve_views.views.first().map_or(0, |v| v.image.width);
    let measured_peak = reset_peak_rss();
    let started = Instant::now();
    let mut eval_seconds = 0.0;
    let mut curve = Vec::new();
    let mut failure = None;
    let summary = train(
        &TrainRequest {
            data: scene.data.clone(),
            out: out.to_path_buf(),
            config,
            resume: false,
            stop_after: None,
            resume_backend: None,
            resume_net_backend: None,
        },
        &mut |report, trainer| {
            progress(BenchProgress::Step {
                schedule_iteration: report.schedule_iteration,
                schedule,
            });
            if failure.is_some() || !(report.iteration.is_multiple_of(eval_every) || report.last) {
                return;
            }
            let t = Instant::now();
            let seconds = t.duration_since(started).as_secs_f64() - eval_seconds;
            match mean_psnr(trainer, &curve_views) {
                Ok(psnr) => {
                    let point = CurvePoint {
                        iteration: report.iteration,
                        seconds,
                        psnr,
                    };
                    curve.push(point);
                    progress(BenchProgress::Point {
                        scene: &scene.name,
                        method,
                        point,
                    });
                }
                Err(e) => failure = Some(e),
            }
            eval_seconds += t.elapsed().as_secs_f64();
        },
    )?;
    if let Some(e) = failure {
        return Err(e);
    }
    let peak_rss_bytes = peak_rss_bytes().filter(|_| measured_peak);
    let seconds = started.elapsed().as_secs_f64() - eval_seconds;
    let mut run = LoadedRun::open(out)?;
    run.use_backend(run.run.train.backend)?;
    // Canonical Gaussians first; the deformed ones at every evaluated time below.
    let mut non_finite = non_finite_gaussians(&run.canonical);
    let mut scores = Vec::new();
    let other = if headline == Split::Val {
        Split::Test
    } else {
        Split::Val
    };
    for split in [headline, other] {
        let report = evaluate(&mut run, split, lpips)?;
        non_finite = non_finite.max(report.non_finite_gaussians);
        scores.push(SplitScore {
            split: split.name().to_string(),
            images: report.images.len(),
            psnr: report.mean_psnr,
            ssim: report.mean_ssim,
            lpips_alex: report.mean_lpips_alex,
            lpips_vgg: report.mean_lpips_vgg,
        });
    }
    Ok(BenchRun {
        scene: scene.name.clone(),
        method,
        run: out.to_path_buf(),
        resolution,
        iterations: summary.iteration,
        schedule_lagged: summary.budget.as_ref().map_or(0, |b| b.lagged),
        seconds,
        peak_rss_bytes,
        gaussians: summary.gaussians,
        non_finite,
        headline: headline.name().to_string(),
        scores,
        curve,
    })
}

/// File name of a run's row ([`BenchRun`] as JSON) in its run directory.
pub const RUN_RECORD: &str = "bench_run.json";

/// Reads the row a bench run wrote into `run_dir` ([`RUN_RECORD`]); the error names the file.
pub fn read_run_record(run_dir: &Path) -> Result<BenchRun, ExperimentError> {
    let path = run_dir.join(RUN_RECORD);
    let text =
        std::fs::read_to_string(&path).map_err(|e| ExperimentError::input(&path, e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| ExperimentError::input(&path, e.to_string()))
}

fn check_request(request: &BenchRequest) -> Result<(), ExperimentError> {
    if request.scenes.is_empty() || request.methods.is_empty() {
        return Err(ExperimentError::config(
            "bench",
            "nothing to run: give at least one scene and one method",
        ));
    }
    if request.eval_every == 0 {
        return Err(ExperimentError::config("eval_every", "must be at least 1"));
    }
    request.config.validate()?;
    std::fs::create_dir_all(&request.out).map_err(|e| ExperimentError::dir(&request.out, e))
}

/// Trains and evaluates every method of `request` on `scene`; each run writes its
/// [`RUN_RECORD`].
fn run_scene(
    request: &BenchRequest,
    scene: &BenchScene,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(BenchProgress<'_>),
) -> Result<Vec<BenchRun>, ExperimentError> {
    let mut runs = Vec::new();
    for &method in &request.methods {
        progress(BenchProgress::Started {
            scene: &scene.name,
            method,
        });
        let config = request.config.clone().with_method(method);
        let out = request.out.join(&scene.name).join(method.to_string());
        let run = bench_one(scene, config, request.eval_every, &out, lpips, progress)?;
        let record = serde_json::to_value(&run)
            .map_err(|e| ExperimentError::output(out.join(RUN_RECORD), e.to_string()))?;
        write_json(&out.join(RUN_RECORD), &record)?;
        progress(BenchProgress::Finished { run: &run });
        runs.push(run);
    }
    Ok(runs)
}

/// Runs every scene × method of `request`, evaluates each with the LPIPS networks of `lpips`,
/// writes the outputs ([`write_outputs`]) and returns the runs (scene-major, in the request's
/// orders).
pub fn run_bench(
    request: &BenchRequest,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(BenchProgress<'_>),
) -> Result<Vec<BenchRun>, ExperimentError> {
    check_request(request)?;
    let mut runs = Vec::new();
    for scene in &request.scenes {
        runs.extend(run_scene(request, scene, lpips, progress)?);
        // The outputs so far, so that an interrupted bench leaves its finished scenes.
        write_outputs(&request.out, &request.config, &runs)?;
        write_picture(&request.out, scene, &runs)?;
    }
    Ok(runs)
}

/// [`run_bench`] without the outputs: trains and evaluates every scene × method, each run
/// writing its [`RUN_RECORD`], for a caller that gathers runs trained apart
/// ([`write_summaries`]).
pub fn run_bench_runs(
    request: &BenchRequest,
    lpips: &EvalLpips,
    progress: &mut dyn FnMut(BenchProgress<'_>),
) -> Result<Vec<BenchRun>, ExperimentError> {
    check_request(request)?;
    let mut runs = Vec::new();
    for scene in &request.scenes {
        runs.extend(run_scene(request, scene, lpips, progress)?);
    }
    Ok(runs)
}

/// Writes the outputs of `runs` into `request.out`: the table, the JSON and the plot
/// ([`write_outputs`]) and the picture of every scene of the request ([`write_picture`]).
pub fn write_summaries(request: &BenchRequest, runs: &[BenchRun]) -> Result<(), ExperimentError> {
    write_outputs(&request.out, &request.config, runs)?;
    for scene in &request.scenes {
        write_picture(&request.out, scene, runs)?;
    }
    Ok(())
}

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "–".to_string(), |v| format!("{v:.digits$}"))
}

/// The steps a run made, with its schedule's lag when it fell behind its budget.
fn steps_cell(r: &BenchRun) -> String {
    if r.schedule_lagged > 0 {
        format!("{} (lagged {})", r.iterations, r.schedule_lagged)
    } else {
        r.iterations.to_string()
    }
}

/// The markdown table: one row per run (headline split first, then the other split), and the
/// published figure for each scene beside ours.
pub fn table(config: &TrainConfig, runs: &[BenchRun]) -> String {
    let mut s = format!(
        "# evogs bench: backbone `{}`, preset `{}`, {}, seed {}\n\n\
         Headline split: lego val, the other scenes test (as D-3DGS reports them). Times are \
         wall clock on the machine as it was (see the README for what else ran); curve \
         evaluations are excluded. LPIPS: AlexNet and VGG16 backbones (– where not computed); \
         D-3DGS publishes VGG16. Non-finite: Gaussians with a NaN or infinite value, canonical \
         or deformed at an evaluated time. Steps: the optimiser steps made; \"lagged N\": under a \
         time budget the schedule fell behind and its last step took N schedule iterations at \
         once (its end compressed into one step: compare such a row with care, or run it again \
         with `--iterations` near its steps).\n\n\
         | scene | method | split | PSNR (dB) | SSIM | LPIPS (Alex) | LPIPS (VGG) | other split PSNR | Gaussians | peak memory (MiB) | training (min) | steps | non-finite | published (D-3DGS) | published (SC-GS) |\n\
         | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- |\n",
        config.backbone,
        config.preset,
        config.length(),
        config.seed
    );
    for r in runs {
        let head = r.score(&r.headline);
        let other = r.scores.iter().find(|x| x.split != r.headline);
        let published = published_for(&r.scene, r.resolution).map_or_else(
            || "–".to_string(),
            |p| {
                format!(
                    "{:.2} / {:.4} / {:.4} ({}, {}×{})",
                    p.psnr, p.ssim, p.lpips, p.split, p.resolution, p.resolution
                )
            },
        );
        let scgs = published_scgs_for(&r.scene).map_or_else(
            || "–".to_string(),
            |p| {
                format!(
                    "{:.2} / {:.3} / {:.4} ({})",
                    p.psnr, p.ssim, p.lpips, p.split
                )
            },
        );
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.1} | {} | {} | {} | {} |\n",
            r.scene,
            r.method,
            r.headline,
            fmt_opt(head.map(|x| x.psnr), 2),
            fmt_opt(head.map(|x| x.ssim), 4),
            fmt_opt(head.and_then(|x| x.lpips_alex), 4),
            fmt_opt(head.and_then(|x| x.lpips_vgg), 4),
            other.map_or_else(
                || "–".to_string(),
                |o| format!("{:.2} ({})", o.psnr, o.split)
            ),
            r.gaussians,
            fmt_opt(r.peak_rss_bytes.map(|b| b as f64 / (1024.0 * 1024.0)), 0),
            r.seconds / 60.0,
            steps_cell(r),
            r.non_finite,
            published,
            scgs
        );
    }
    s
}

/// Writes `bench.md`, `bench.json` and `bench.png` into `out`, each atomically.
pub fn write_outputs(
    out: &Path,
    config: &TrainConfig,
    runs: &[BenchRun],
) -> Result<(), ExperimentError> {
    write_bytes(&out.join("bench.md"), table(config, runs).as_bytes())?;
    write_json(
        &out.join("bench.json"),
        &serde_json::json!({
            "config": config,
            "runs": runs,
            "published": PUBLISHED,
            "published_scgs": PUBLISHED_SCGS,
        }),
    )?;
    let png = out.join("bench.png");
    let image = bench_plot::plot(runs)
        .map_err(|problem| ExperimentError::output(&png, format!("plotting: {problem}")))?;
    write_png(&png, &image)
}

/// Side of a picture cell in pixels.
const CELL: u32 = 256;

/// `image` scaled to a `CELL`-wide cell (nearest pixel; D-NeRF images are square).
fn cell(image: &ImageRgb) -> image::RgbImage {
    let (w, h) = (image.width.max(1), image.height.max(1));
    let ch = (CELL as u64 * h as u64 / w as u64).max(1) as u32;
    image::RgbImage::from_fn(CELL, ch, |x, y| {
        let sx = (x as u64 * w as u64 / CELL as u64) as u32;
        let sy = (y as u64 * h as u64 / ch as u64) as u32;
        image::Rgb(image.get(sx, sy).map(evogs_io::image_io::to_u8))
    })
}

/// Writes `<scene>.png`: one row per time (the earliest, middle and latest view of the scene's
/// headline split), columns ground truth then each method of `runs` for this scene.
pub fn write_picture(
    out: &Path,
    scene: &BenchScene,
    runs: &[BenchRun],
) -> Result<(), ExperimentError> {
    let runs: Vec<&BenchRun> = runs.iter().filter(|r| r.scene == scene.name).collect();
    if runs.is_empty() {
        return Ok(());
    }
    let mut loaded = Vec::with_capacity(runs.len());
    for r in &runs {
        let mut run = LoadedRun::open(&r.run)?;
        run.use_backend(run.run.train.backend)?;
        loaded.push(run);
    }
    let c = &loaded[0].run.train;
    let views = load_split(
        &scene.data,
        headline_split(&scene.name),
        c.time_from,
        c.background.rgb(),
        c.downscale,
    )?;
    let mut order: Vec<usize> = (0..views.views.len()).collect();
    order.sort_by(|&a, &b| views.views[a].time.total_cmp(&views.views[b].time));
    let Some(&last) = order.last() else {
        return Ok(());
    };
    let picks = [order[0], order[order.len() / 2], last];
    let mut rows = Vec::new();
    for &k in &picks {
        let v = &views.views[k];
        let mut cells = vec![cell(&v.image)];
        for run in &mut loaded {
            let image = evogs_eval::render::render_at(run, &v.camera, v.time)?;
            cells.push(cell(&image));
        }
        rows.push(cells);
    }
    let (cw, ch) = (CELL, rows[0][0].height());
    let gap = 4;
    let cols = rows[0].len() as u32;
    let mut canvas = image::RgbImage::from_pixel(
        cols * cw + (cols - 1) * gap,
        3 * ch + 2 * gap,
        image::Rgb([255, 255, 255]),
    );
    for (ri, row) in rows.iter().enumerate() {
        for (ci, img) in row.iter().enumerate() {
            image::imageops::replace(
                &mut canvas,
                img,
                i64::from(ci as u32 * (cw + gap)),
                i64::from(ri as u32 * (ch + gap)),
            );
        }
    }
    write_png(&out.join(format!("{}.png", scene.name)), &canvas)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_are_named_by_their_directory() {
        let s = BenchScene::from_dir(Path::new("/data/dnerf-lego"));
        assert_eq!(s.name, "lego");
        assert_eq!(BenchScene::from_dir(Path::new("hook")).name, "hook");
    }

    #[test]
    fn lego_reports_val_the_others_test() {
        assert_eq!(headline_split("lego"), Split::Val);
        assert_eq!(headline_split("jumpingjacks"), Split::Test);
    }

    #[test]
    fn published_figures_prefer_the_same_resolution() {
        let p = published_for("hook", 400).unwrap();
        assert_eq!((p.resolution, p.psnr), (400, 37.77));
        let p = published_for("hook", 800).unwrap();
        assert_eq!((p.resolution, p.psnr), (800, 37.42));
        // Lego has only the 800×800 val figure.
        let p = published_for("lego", 400).unwrap();
        assert_eq!((p.resolution, p.split, p.psnr), (800, "val", 33.07));
        assert!(published_for("mine", 400).is_none());
        // SC-GS's table: the issue's figures, and none for lego.
        let p = published_scgs_for("jumpingjacks").unwrap();
        assert_eq!((p.method, p.psnr, p.split), ("SC-GS", 41.13, "test"));
        assert_eq!(published_scgs_for("mutant").unwrap().psnr, 45.19);
        assert!(published_scgs_for("lego").is_none());
        let mean = PUBLISHED_SCGS.iter().map(|p| p.psnr).sum::<f64>() / 7.0;
        assert!((mean - 43.31).abs() < 0.005, "the table's average: {mean}");
    }

    #[test]
    fn run_records_read_back_and_bad_ones_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let run = BenchRun {
            scene: "hook".into(),
            method: Method::Evogs,
            run: dir.path().to_path_buf(),
            resolution: 400,
            iterations: 12_000,
            schedule_lagged: 2_470,
            seconds: 1234.5678901234,
            peak_rss_bytes: Some(554 << 20),
            gaussians: 40_000,
            non_finite: 0,
            headline: "test".into(),
            scores: vec![SplitScore {
                split: "test".into(),
                images: 20,
                psnr: 31.234_567_890_123,
                ssim: 0.97,
                lpips_alex: None,
                lpips_vgg: Some(0.0416),
            }],
            curve: vec![CurvePoint {
                iteration: 2000,
                seconds: 0.1 + 0.2,
                psnr: 26.03,
            }],
        };
        write_json(
            &dir.path().join(RUN_RECORD),
            &serde_json::to_value(&run).unwrap(),
        )
        .unwrap();
        assert_eq!(read_run_record(dir.path()).unwrap(), run);
        let missing = read_run_record(&dir.path().join("none"))
            .unwrap_err()
            .to_string();
        assert!(
            missing.contains("none") && missing.contains(RUN_RECORD),
            "{missing}"
        );
        std::fs::write(dir.path().join(RUN_RECORD), r#"{"scene": "hook"}"#).unwrap();
        let bad = read_run_record(dir.path()).unwrap_err().to_string();
        assert!(bad.contains(RUN_RECORD) && bad.contains("method"), "{bad}");
        assert_eq!(bad.lines().count(), 1, "{bad}");
    }

    /// A run whose schedule fell behind its budget says so in its steps cell; one that kept
    /// pace shows its steps alone.
    #[test]
    fn the_table_gives_each_run_its_steps_and_marks_a_lagged_schedule() {
        let run = |scene: &str, lagged: u64| BenchRun {
            scene: scene.into(),
            method: Method::Baseline,
            run: PathBuf::from("/nowhere"),
            resolution: 400,
            iterations: 5_832,
            schedule_lagged: lagged,
            seconds: 900.0,
            peak_rss_bytes: None,
            gaussians: 10_000,
            non_finite: 0,
            headline: "test".into(),
            scores: Vec::new(),
            curve: Vec::new(),
        };
        let config = TrainConfig::preset(evogs_train::Preset::Tiny);
        let table = table(&config, &[run("hook", 2_470), run("mutant", 0)]);
        let steps: Vec<String> = table
            .lines()
            .filter(|l| l.starts_with("| hook") || l.starts_with("| mutant"))
            .map(|l| l.split('|').map(str::trim).nth(12).unwrap().to_string())
            .collect();
        assert_eq!(steps, ["5832 (lagged 2470)", "5832"], "{table}");
        let header = table.lines().find(|l| l.starts_with("| scene")).unwrap();
        assert_eq!(header.split('|').map(str::trim).nth(12), Some("steps"));
    }

    #[test]
    fn peak_memory_reads_and_resets_on_linux() {
        if std::fs::metadata("/proc/self/status").is_err() {
            return;
        }
        let held = vec![1u8; 64 << 20];
        let peak = peak_rss_bytes().unwrap();
        assert!(peak >= 64 << 20, "{peak}");
        drop(held);
        if reset_peak_rss() {
            // The 64 MiB are gone, so the peak after the reset is lower.
            assert!(peak_rss_bytes().unwrap() < peak);
        }
    }
}
