//! Rendering a run from any camera at any time, time sweeps, and exporting a frame's deformed
//! Gaussians as a standard 3DGS PLY.
//!
//! Any finite time is accepted: between training frames, and before or beyond the training
//! range [0, 1]. Rendering uses the backbone's read-only query (EvoGS: evo-state's forward,
//! never committed; nothing is written to the buffer). Outside [0, 1]:
//! - EvoGS's Φ clamps its cubic B-spline time encoding to [0, 1] (tiny-nn), so z = Φ(x, t) is the
//!   observation at the nearest end; the evolution's prior uses the latest buffer frames strictly
//!   before t and extrapolates them linearly, `d̂ = d̃_k1 + s (d̃_k1 − d̃_k2)` with
//!   `s = (t − t_k1)/(t_k1 − t_k2)`, blended with z by the gain K. Before the first frame there
//!   is no history and d̃ = z (Φ at t = 0).
//! - The baseline's sinusoidal time encoding is evaluated as it is (D-3DGS does not clamp).
//!
//! Far outside [0, 1] both are extrapolations, not reconstructions.

use std::path::{Path, PathBuf};

use evogs_io::{ImageRgb, save_png, write_ply};
use splat_raster::{Camera, RenderOptions};

use crate::error::TrainError;
use crate::run::LoadedRun;

fn check_time(time: f32) -> Result<(), TrainError> {
    if !time.is_finite() {
        return Err(TrainError::config(
            "time",
            format!("{time} is not a finite number"),
        ));
    }
    Ok(())
}

/// Renders `run` from `camera` at any finite `time` (see the module docs for times outside
/// [0, 1]) over the run's background, colours clamped to [0, 1]. Read-only.
pub fn render_at(run: &mut LoadedRun, camera: &Camera, time: f32) -> Result<ImageRgb, TrainError> {
    check_time(time)?;
    let g = run.deformed(time)?;
    let opts = RenderOptions {
        background: run.run.train.background.rgb(),
        sh_degree: None,
    };
    let out = run.raster.forward(g.view(), camera, &opts)?;
    Ok(ImageRgb {
        width: camera.width,
        height: camera.height,
        pixels: out
            .color
            .iter()
            .map(|c| c.map(|v| v.clamp(0.0, 1.0)))
            .collect(),
    })
}

/// What a sweep wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// The frames, `frame_0000.png`, ..., in time order.
    pub frames: Vec<PathBuf>,
    /// `strip.png`: the frames side by side.
    pub strip: PathBuf,
}

/// Renders `count` (≥ 2) frames at times `k / (count − 1)` from one camera into `dir`, plus a
/// strip image of all frames side by side.
pub fn sweep(
    run: &mut LoadedRun,
    camera: &Camera,
    count: usize,
    dir: &Path,
) -> Result<Sweep, TrainError> {
    if count < 2 {
        return Err(TrainError::config(
            "sweep",
            format!("{count} frames; a sweep needs at least 2"),
        ));
    }
    std::fs::create_dir_all(dir).map_err(|e| TrainError::io(dir, e))?;
    let (w, h) = (camera.width, camera.height);
    let mut strip = ImageRgb::filled(w * count as u32, h, [0.0; 3]);
    let mut frames = Vec::with_capacity(count);
    for k in 0..count {
        let t = k as f32 / (count - 1) as f32;
        let img = render_at(run, camera, t)?;
        for y in 0..h as usize {
            let src = &img.pixels[y * w as usize..(y + 1) * w as usize];
            let at = y * (w as usize * count) + k * w as usize;
            strip.pixels[at..at + w as usize].copy_from_slice(src);
        }
        let path = dir.join(format!("frame_{k:04}.png"));
        save_png(&path, &img)?;
        frames.push(path);
    }
    let strip_path = dir.join("strip.png");
    save_png(&strip_path, &strip)?;
    Ok(Sweep {
        frames,
        strip: strip_path,
    })
}

/// Writes the deformed Gaussians of `run` at any finite `time` as a 3DGS PLY (atomically); returns how many.
pub fn export_frame(run: &mut LoadedRun, time: f32, out: &Path) -> Result<usize, TrainError> {
    check_time(time)?;
    let g = run.deformed(time)?;
    write_ply(out, g.view())?;
    Ok(g.len())
}
