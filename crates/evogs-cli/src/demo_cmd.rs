//! `evogs demo [--quick]`: needs no files. Builds the embedded synthetic scene
//! (`evogs_synth::embedded_scene`, written in the D-NeRF layout under `OUT/scene`), trains the baseline
//! (D-3DGS) and EvoGS with the same preset and iteration budget, evaluates both on the test split
//! (renders under `OUT/<method>/renders/test/`), renders a fixed-camera time sweep with its strip
//! for each (`OUT/<method>/sweep/strip.png`, from the first test camera), and returns a
//! side-by-side table.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use evogs_eval::eval::EvalLpips;
use evogs_experiments::ablate::train_and_evaluate_with_progress;
use evogs_io::Split;
use evogs_synth::{embedded_scene, write_dnerf};
use evogs_train::data::load_split;
use evogs_train::{Method, Preset, TrainConfig};

use crate::render::{RenderArgs, render_run};
use crate::shared_args::RasterArgs;

/// Arguments of `evogs demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// A short run (1 000 iterations per method instead of 5 000).
    #[arg(long)]
    pub quick: bool,

    /// Output directory (scene, both runs, renders, `demo.md`).
    #[arg(long, value_name = "DIR", default_value = "evogs-demo")]
    pub out: PathBuf,

    /// The rasterizer backend of training, evaluation and the sweeps.
    #[command(flatten)]
    pub raster: RasterArgs,

    /// Iterations per method (overrides --quick).
    #[arg(long, allow_negative_numbers = true, value_name = "N", hide = true, value_parser = crate::shared_args::whole::<u64>(1))]
    pub iterations: Option<u64>,
}

/// One method's results.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoRow {
    /// `baseline` or `evogs`.
    pub method: Method,
    /// Mean test PSNR (dB).
    pub psnr: f64,
    /// Mean test SSIM.
    pub ssim: f64,
    /// Fixed-camera flicker (rendered).
    pub flicker: f64,
    /// Trajectory jitter.
    pub jitter: f64,
    /// Training time (s).
    pub seconds: f64,
    /// Final Gaussian count.
    pub gaussians: usize,
    /// Bytes of the evolution state, buffer and residual memory (0 for the baseline).
    pub state_bytes: usize,
}

/// The side-by-side table (markdown).
pub fn table(iterations: u64, rows: &[DemoRow]) -> String {
    let mut s = format!(
        "# evogs demo: embedded synthetic scene, {iterations} iterations per method (preset tiny)\n\n\
         | method | PSNR (dB) | SSIM | flicker | jitter | training (s) | Gaussians | state (KiB) |\n\
         | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n"
    );
    for r in rows {
        s += &format!(
            "| {} | {:.2} | {:.4} | {:.5} | {:.3e} | {:.1} | {} | {:.1} |\n",
            r.method,
            r.psnr,
            r.ssim,
            r.flicker,
            r.jitter,
            r.seconds,
            r.gaussians,
            r.state_bytes as f64 / 1024.0
        );
    }
    s
}

/// Where the demo's pictures are and the command that shows them (the end of `demo.md` and of
/// the demo's output).
pub fn where_to_look(out: &Path) -> String {
    let o = out.display();
    format!(
        "\nPictures: `{o}/baseline/sweep/` and `{o}/evogs/sweep/` (the first test camera at 8 \
         times), `{o}/<method>/renders/test/` (every test view). Look at both runs side by side \
         in a browser: `evogs view {o}/evogs {o}/baseline`.\n"
    )
}

/// Runs `evogs demo`; returns the iteration budget and one row per method.
pub fn run_demo(args: &DemoArgs) -> Result<(u64, Vec<DemoRow>)> {
    let iterations = args
        .iterations
        .unwrap_or(if args.quick { 1_000 } else { 5_000 });
    let data = args.out.join("scene");
    let scene = embedded_scene().context("building the embedded scene")?;
    write_dnerf(&scene, &data)?;
    let test = load_split(&data, Split::Test, Default::default(), [0.0; 3], 1.0)?;
    let first = test
        .views
        .first()
        .context("the embedded scene has no test view")?;
    let camera = args.out.join("sweep_camera.json");
    evogs_io::write_nerfies_camera(&camera, &evogs_io::CameraInfo::pinhole(first.camera))?;
    // Say once which backend runs (and why), on stderr beside the progress: stdout is the
    // table. Training, evaluation and the sweeps then open their own.
    let (_, info) = splat_raster::select_rasterizer(args.raster.backend)?;
    eprintln!("evogs demo: {info}");
    let mut rows = Vec::new();
    let mut progress = crate::progress::Counted::new(2 * iterations as usize, "iteration")?;
    for method in [Method::Baseline, Method::Evogs] {
        let mut config = TrainConfig::preset(Preset::Tiny).with_iterations(iterations);
        config = config.with_method(method);
        config.backend = args.raster.backend;
        let out = args.out.join(method.to_string());
        let scores = train_and_evaluate_with_progress(
            &data,
            &out,
            config,
            false,
            &EvalLpips::default(),
            &mut |_| progress.inc(),
        )?;
        rows.push(DemoRow {
            method,
            psnr: scores.psnr,
            ssim: scores.ssim,
            flicker: scores.flicker,
            jitter: scores.jitter,
            seconds: scores.seconds,
            gaussians: scores.gaussians,
            state_bytes: scores.state_bytes,
        });
        render_run(
            &out,
            &RenderArgs {
                ply: None,
                run: Some(out.clone()),
                camera: Some(evogs_video::camera_path::CameraSpec::File(camera.clone())),
                time: None,
                sweep: Some(8),
                show_controls: false,
                out: out.join("sweep"),
                background: [0.0; 3],
                width: None,
                height: None,
                raster: args.raster,
            },
        )?;
    }
    progress.finish();
    let text = table(iterations, &rows) + &where_to_look(&args.out);
    let path = args.out.join("demo.md");
    let tmp = args.out.join("demo.md.tmp");
    std::fs::write(&tmp, &text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, &path).with_context(|| format!("writing {}", path.display()))?;
    Ok((iterations, rows))
}
