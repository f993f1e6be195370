//! `evogs render`: Gaussians + camera → PNG, with the culling statistics on stdout.

use std::path::Path;

use anyhow::{Context, Result, bail};
use evogs_io::{ImageRgb, read_nerfies_camera, read_ply, save_png};
use splat_raster::{Camera, Gaussians, RenderOptions, select_rasterizer};

use evogs_video::camera_path::CameraSpec;

use crate::args::RenderArgs;
use crate::demo_scene;

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
        return crate::render_run::render_run(run, args);
    }
    check_output_name(&args.out)?;
    let mut warnings = Vec::new();
    let (gaussians, camera, source, viewpoint): (Gaussians, Camera, String, String) =
        match (&args.ply, &args.camera) {
            (Some(_), Some(CameraSpec::Dataset { .. })) => {
                bail!("--camera dataset:SPLIT:INDEX needs --run (the run's dataset)")
            }
            (Some(ply), Some(CameraSpec::File(camera_path))) => {
                let loaded = read_ply(ply)?;
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
    let (raster, backend) = select_rasterizer(args.backend)?;
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
