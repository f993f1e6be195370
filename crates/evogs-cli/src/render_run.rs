//! `evogs render --run`: a trained run from a camera (a nerfies file or a dataset camera) at a
//! time, or a time sweep.

use std::path::Path;

use anyhow::{Context, Result};
use evogs_eval::LoadedRun;
use evogs_eval::render::{render_at, sweep};
use evogs_io::read_nerfies_camera;
use evogs_video::camera_path::{CameraSpec, dataset_camera};
use splat_raster::Camera;

use crate::args::RenderArgs;
use crate::render::{RenderReport, check_output_name, resize_camera};

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
    let backend = loaded.use_backend(args.backend)?;
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
            let image = render_at(&mut loaded, &camera, time)?;
            evogs_io::save_png(&args.out, &image)?;
            format!("rendered {} at time {time}", run.display())
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
