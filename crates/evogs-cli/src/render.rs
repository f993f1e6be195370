//! `evogs render`: Gaussians + camera → PNG, with the culling statistics on stdout; a trained
//! run from a camera (a nerfies file or a dataset camera) at a time, or a time sweep
//! ([`render_run`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use evogs_eval::LoadedRun;
use evogs_eval::render::{CONTROL_COLOUR, draw_points, render_at, sweep};
use evogs_io::{ImageRgb, read_gaussians, read_nerfies_camera, save_png};
use splat_raster::{Camera, Gaussians, RenderOptions, select_rasterizer};

use evogs_video::camera_path::{CameraSpec, dataset_camera};

use crate::demo_scene;
use crate::shared_args::{RasterArgs, parse_background};

/// Renders larger than this many pixels are refused (a corrupt or mistyped size would otherwise
/// exhaust memory): 8192 × 8192.
pub const MAX_PIXELS: u64 = 8192 * 8192;

/// What a render produced, for printing.
#[derive(Debug)]
pub struct RenderReport {
    /// Warnings about the inputs (non-finite rows, ignored camera distortion).
    pub warnings: Vec<String>,
    /// The backend that rendered, and why (one line).
    pub backend: String,
    /// The rasterizer's one-line culling statistics.
    pub stats: String,
    /// Output size.
    pub width: u32,
    /// Output size.
    pub height: u32,
}

pub use evogs_video::camera_path::resize_camera;

pub(crate) fn check_output_name(out: &Path) -> Result<()> {
    let is_png = out
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        bail!("{}: output must be a .png file", out.display());
    }
    Ok(())
}

/// Loads the inputs (or builds the demo scene), renders and writes the PNG.
pub fn run_render(args: &RenderArgs) -> Result<RenderReport> {
    if let Some(run) = &args.run {
        return render_run(run, args);
    }
    check_output_name(&args.out)?;
    let mut warnings = Vec::new();
    let (gaussians, camera, source, viewpoint): (Gaussians, Camera, String, String) =
        match (&args.ply, &args.camera) {
            (Some(_), Some(CameraSpec::Dataset { .. })) => {
                bail!("--camera dataset:SPLIT:INDEX needs --run (the run's dataset)")
            }
            (Some(ply), Some(CameraSpec::File(camera_path))) => {
                let loaded = read_gaussians(ply)?;
                if loaded.nonfinite_rows > 0 {
                    warnings.push(format!(
                        "{}: {} Gaussian(s) hold non-finite values; they are culled",
                        ply.display(),
                        loaded.nonfinite_rows
                    ));
                }
                let info = read_nerfies_camera(camera_path)?;
                if let Some(w) = info.warning() {
                    warnings.push(format!("{}: {w}", camera_path.display()));
                }
                let camera = resize_camera(info.camera, args.width, args.height);
                (
                    loaded.gaussians,
                    camera,
                    ply.display().to_string(),
                    camera_path.display().to_string(),
                )
            }
            (None, None) => {
                let camera = demo_scene::default_camera(
                    args.width.unwrap_or(demo_scene::DEFAULT_WIDTH),
                    args.height.unwrap_or(demo_scene::DEFAULT_HEIGHT),
                );
                (
                    demo_scene::build(),
                    camera,
                    "the demo scene".to_string(),
                    "the default camera".to_string(),
                )
            }
            // clap enforces that --ply comes with --camera.
            _ => bail!("--camera needs --ply or --run"),
        };
    let pixels = camera.width as u64 * camera.height as u64;
    if pixels > MAX_PIXELS {
        bail!(
            "{viewpoint}: image size {}x{} exceeds the limit of {MAX_PIXELS} pixels",
            camera.width,
            camera.height
        );
    }
    let options = RenderOptions {
        background: args.background,
        sh_degree: None,
    };
    let (raster, backend) = select_rasterizer(args.raster.backend)?;
    let output = raster
        .forward(gaussians.view(), &camera, &options)
        .with_context(|| format!("rendering {source} from {viewpoint}"))?;
    let image = ImageRgb {
        width: output.width,
        height: output.height,
        pixels: output.color,
    };
    save_png(&args.out, &image)?;
    Ok(RenderReport {
        warnings,
        backend: backend.to_string(),
        stats: output.stats.to_string(),
        width: output.width,
        height: output.height,
    })
}

/// Arguments of `evogs render`.
#[derive(Debug, Args)]
#[command(
    after_help = "Without --ply and --camera, renders the built-in procedural demo scene \
                        (a torus, spheres and a ground disc) from a default camera."
)]
pub struct RenderArgs {
    /// Gaussians to render: a 3DGS PLY, a compressed PLY or a `.splat` (what `evogs export`
    /// writes). Needs --camera.
    #[arg(long, value_name = "FILE", requires = "camera", conflicts_with = "run")]
    pub ply: Option<PathBuf>,

    /// A trained run to render at --time (or a --sweep of times). Needs --camera.
    #[arg(long, value_name = "RUN", requires = "camera")]
    pub run: Option<PathBuf>,

    /// Camera to render from: a nerfies camera JSON file, or dataset:SPLIT:INDEX (a camera of
    /// the run's dataset, at the run's resolution; needs --run). Needs --ply or --run.
    #[arg(long, value_name = "CAMERA")]
    pub camera: Option<CameraSpec>,

    /// Time at which to render a run: training times lie in [0, 1]; any finite time is accepted
    /// (between frames, or beyond them: Φ's B-spline clamps to [0, 1], EvoGS's prior
    /// extrapolates the last frames) [default: the dataset camera's time, else 0].
    #[arg(
        long,
        value_name = "T",
        requires = "run",
        allow_negative_numbers = true
    )]
    pub time: Option<f32>,

    /// Render N frames of a run at times evenly spaced over [0, 1] into the folder --out, plus
    /// strip.png with all frames side by side.
    #[arg(long, allow_negative_numbers = true, value_name = "N", requires = "run", value_parser = clap::value_parser!(u32).range(2..=1000))]
    pub sweep: Option<u32>,

    /// Draw the run's control points over the image (magenta discs ringed in black: the motion
    /// skeleton of a `--backbone scgs` run, where each is at the time rendered).
    #[arg(long, requires = "run", conflicts_with = "sweep")]
    pub show_controls: bool,

    /// Output PNG image (a folder with --sweep), written atomically (temporary file, rename).
    #[arg(long, value_name = "IMAGE.png")]
    pub out: PathBuf,

    /// Background colour behind the Gaussians, three numbers in [0, 1] (a run uses its own).
    #[arg(long, value_name = "R,G,B", default_value = "0,0,0", value_parser = parse_background)]
    pub background: [f32; 3],

    /// Image width in pixels [demo scene default: 800]. With --camera, the camera is resized to
    /// this width (intrinsics scaled to match).
    #[arg(long, allow_negative_numbers = true, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,

    /// Image height in pixels [demo scene default: 600]. With --camera, the camera is resized to
    /// this height (intrinsics scaled to match).
    #[arg(long, allow_negative_numbers = true, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,

    /// The rasterizer backend.
    #[command(flatten)]
    pub raster: RasterArgs,
}

/// A camera named on the command line, read: the camera, the time it carries (a dataset
/// camera's), and a warning about what rendering ignores (skew, distortion).
pub struct ResolvedCamera {
    /// The camera.
    pub camera: Camera,
    /// The dataset frame's time, for a dataset camera.
    pub time: Option<f32>,
    /// A one-line warning.
    pub warning: Option<String>,
}

/// Reads `spec`: a nerfies camera file, or a camera of `run`'s dataset at the run's resolution.
pub fn resolve_camera(spec: &CameraSpec, run: &LoadedRun) -> Result<ResolvedCamera> {
    Ok(match spec {
        CameraSpec::File(path) => {
            let info = read_nerfies_camera(path)?;
            ResolvedCamera {
                camera: info.camera,
                time: None,
                warning: info.warning().map(|w| format!("{}: {w}", path.display())),
            }
        }
        CameraSpec::Dataset { split, index } => {
            let (camera, time) = dataset_camera(run, *split, *index)?;
            ResolvedCamera {
                camera,
                time: Some(time),
                warning: None,
            }
        }
    })
}

/// Renders `run` as `args` ask: one image at `--time`, or `--sweep N` frames into a folder.
pub fn render_run(run: &Path, args: &RenderArgs) -> Result<RenderReport> {
    let spec = args.camera.as_ref().context("--run needs --camera")?;
    let mut loaded = LoadedRun::open(run)?;
    let backend = loaded.use_backend(args.raster.backend)?;
    let resolved = resolve_camera(spec, &loaded)?;
    let warnings = resolved.warning.into_iter().collect();
    let camera = resize_camera(resolved.camera, args.width, args.height);
    let stats = match args.sweep {
        Some(n) => {
            let s = sweep(&mut loaded, &camera, n as usize, &args.out)?;
            format!(
                "rendered {} frames and {}",
                s.frames.len(),
                s.strip.display()
            )
        }
        None => {
            check_output_name(&args.out)?;
            let time = args.time.or(resolved.time).unwrap_or(0.0);
            let mut image = render_at(&mut loaded, &camera, time)?;
            let mut drawn = String::new();
            if args.show_controls {
                let name = loaded.backbone.name();
                let points = loaded.backbone.control_points_at(time)?.with_context(|| {
                    format!(
                        "--show-controls: the run's backbone ({name}) has no control points \
                         (those of --backbone scgs)"
                    )
                })?;
                let n = draw_points(&mut image, &camera, &points, CONTROL_COLOUR);
                drawn = format!(" with {n} of its {} control points in view", points.len());
            }
            evogs_io::save_png(&args.out, &image)?;
            format!("rendered {} at time {time}{drawn}", run.display())
        }
    };
    Ok(RenderReport {
        warnings,
        backend: backend.to_string(),
        stats,
        width: camera.width,
        height: camera.height,
    })
}
