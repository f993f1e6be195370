//! `evogs render --run`: a trained run from a nerfies camera at a time, or a time sweep.

use std::path::Path;

use anyhow::{Context, Result};
use evogs_io::read_nerfies_camera;
use evogs_train::LoadedRun;
use evogs_train::render::{render_at, sweep};

use crate::args::RenderArgs;
use crate::render::{RenderReport, check_output_name, resize_camera};

/// Renders `run` as `args` ask: one image at `--time`, or `--sweep N` frames into a folder.
pub fn render_run(run: &Path, args: &RenderArgs) -> Result<RenderReport> {
    let camera_path = args.camera.as_ref().context("--run needs --camera")?;
    let mut loaded = LoadedRun::open(run)?;
    let backend = loaded.use_backend(args.backend)?;
    let info = read_nerfies_camera(camera_path)?;
    let mut warnings = Vec::new();
    if let Some(w) = info.warning() {
        warnings.push(format!("{}: {w}", camera_path.display()));
    }
    let camera = resize_camera(info.camera, args.width, args.height);
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
            let image = render_at(&mut loaded, &camera, args.time)?;
            evogs_io::save_png(&args.out, &image)?;
            format!("rendered {} at time {}", run.display(), args.time)
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
