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
use splat_raster::{Camera, ForwardOutput, Gaussians, RenderOptions};
use strum::{Display, EnumString, IntoStaticStr, VariantNames};

use evogs_backbones::{OneWord, unknown_message};
use evogs_train::TrainError;
use evogs_train::run::write_json;

use crate::loaded::LoadedRun;

/// The colour control points are drawn in (`evogs render --show-controls`, the viewer's
/// "control points"): magenta, apart from the colours of the D-NeRF scenes.
pub const CONTROL_COLOUR: [f32; 3] = [1.0, 0.1, 0.9];

/// Draws `points` over `image` as seen by `camera`: a filled disc of radius 2.5 px in `colour`
/// ringed in black, for each point in front of the camera (camera-space depth above 1e-3) and
/// inside the image (`evogs render --show-controls`: SC-GS's control points over the render).
/// Returns how many were drawn.
pub fn draw_points(
    image: &mut ImageRgb,
    camera: &Camera,
    points: &[[f32; 3]],
    colour: [f32; 3],
) -> usize {
    const RADIUS: f32 = 2.5;
    const RING: f32 = 1.2;
    let (w, h) = (image.width as i64, image.height as i64);
    let mut drawn = 0;
    for p in points {
        let c = camera.world_to_camera(glam::Vec3::from(*p));
        // In front of the camera (a NaN coordinate is not).
        if c.z.partial_cmp(&1e-3) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        let u = camera.fx * c.x / c.z + camera.cx;
        let v = camera.fy * c.y / c.z + camera.cy;
        if !((0.0..w as f32).contains(&u) && (0.0..h as f32).contains(&v)) {
            continue;
        }
        drawn += 1;
        let reach = (RADIUS + RING).ceil() as i64;
        let (ui, vi) = (u.floor() as i64, v.floor() as i64);
        for y in (vi - reach).max(0)..=(vi + reach).min(h - 1) {
            for x in (ui - reach).max(0)..=(ui + reach).min(w - 1) {
                let d = ((x as f32 + 0.5 - u).powi(2) + (y as f32 + 0.5 - v).powi(2)).sqrt();
                let pixel = &mut image.pixels[(y * w + x) as usize];
                if d <= RADIUS {
                    *pixel = colour;
                } else if d <= RADIUS + RING {
                    *pixel = [0.0; 3];
                }
            }
        }
    }
    drawn
}

/// Renders `run` from `camera` at any finite `time` (see the module docs for times outside
/// [0, 1]) over the run's background, colours clamped to [0, 1]. Read-only.
pub fn render_at(run: &mut LoadedRun, camera: &Camera, time: f32) -> Result<ImageRgb, TrainError> {
    let g = run.deformed(time)?;
    render_deformed(run, &g, camera, &mut ForwardOutput::default())
}

/// The second half of [`render_at`]: rasterizes Gaussians already deformed by `run` (its
/// [`LoadedRun::deformed`] at some time) from `camera` over the run's background, colours
/// clamped to [0, 1], through `fwd`, whose buffers the rasterizer reuses
/// ([`splat_raster::Rasterizer::forward_into`]; start from `ForwardOutput::default()`). For
/// callers that render view after view, one time from many cameras (the viewer).
pub fn render_deformed(
    run: &LoadedRun,
    g: &Gaussians,
    camera: &Camera,
    fwd: &mut ForwardOutput,
) -> Result<ImageRgb, TrainError> {
    let opts = RenderOptions {
        background: run.run.train.background.rgb(),
        sh_degree: None,
    };
    run.raster.forward_into(g.view(), camera, &opts, fwd)?;
    Ok(ImageRgb {
        width: camera.width,
        height: camera.height,
        pixels: fwd
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
    std::fs::create_dir_all(dir).map_err(|e| TrainError::file(dir, e.to_string()))?;
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
    let g = run.deformed(time)?;
    write_ply(out, g.view())?;
    Ok(g.len())
}

/// The file formats of [`export_sequence`].
#[derive(EnumString, Display, IntoStaticStr, VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = String, parse_err_fn = unknown_message::<Self>)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ExportFormat {
    /// The INRIA 3DGS PLY (every SH band, f32; DESIGN §2.2).
    Ply,
    /// PlayCanvas/SuperSplat's compressed PLY (`evogs_io::compressed_ply`: chunks of 256 in
    /// Morton order, quantised to 8 to 11 bits a value, higher SH bands as one byte each).
    #[serde(rename = "compressed-ply")]
    #[strum(serialize = "compressed-ply")]
    CompressedPly,
    /// The 32-byte `.splat` of web viewers (`evogs_io::splat`: DC colour only, 8-bit colour and
    /// rotation).
    Splat,
}

impl ExportFormat {
    /// The file extension (`compressed.ply` for the compressed PLY: SuperSplat tells the two PLY
    /// layouts apart by it).
    pub fn extension(self) -> &'static str {
        match self {
            Self::Ply => "ply",
            Self::CompressedPly => "compressed.ply",
            Self::Splat => "splat",
        }
    }

    /// The format a file name says (`.ply`, `.compressed.ply`, `.splat`, any case), if any.
    pub fn of_path(path: &Path) -> Option<Self> {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        [Self::CompressedPly, Self::Ply, Self::Splat]
            .into_iter()
            .find(|f| name.ends_with(&format!(".{}", f.extension())))
    }
}

impl OneWord for ExportFormat {
    const FIELD: &'static str = "format";
    const NOUN: &'static str = "export format";
}

/// Writes the deformed Gaussians of `run` at `time` in `format` (atomically); returns how many.
pub fn export_frame_as(
    run: &mut LoadedRun,
    time: f32,
    format: ExportFormat,
    out: &Path,
) -> Result<usize, TrainError> {
    let g = run.deformed(time)?;
    match format {
        ExportFormat::Ply => {
            write_ply(out, g.view())?;
            Ok(g.len())
        }
        ExportFormat::CompressedPly => Ok(evogs_io::write_compressed_ply(out, g.view())?),
        ExportFormat::Splat => Ok(evogs_io::write_splat(out, g.view())?),
    }
}

/// `sequence.json` of an exported sequence.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Sequence {
    /// The files' format.
    pub format: ExportFormat,
    /// Number of frames.
    pub count: usize,
    /// The file of each frame, in time order.
    pub files: Vec<String>,
    /// The time of each frame.
    pub times: Vec<f32>,
    /// Gaussians in each file.
    pub gaussians: Vec<usize>,
    /// The canonical Gaussians' bounding box: least and greatest mean per axis.
    pub bounds: [[f32; 3]; 2],
}

/// Exports `count` (≥ 1) frames at times `k / (count − 1)` (0 for one frame) into `dir`:
/// `frame_0000.<ext>`, … and `sequence.json`, all appearing together (`evogs_io::atomic::
/// StagedFiles`, `sequence.json` last): an error half way leaves `dir` as it was.
pub fn export_sequence(
    run: &mut LoadedRun,
    count: usize,
    format: ExportFormat,
    dir: &Path,
) -> Result<Sequence, TrainError> {
    if count == 0 {
        return Err(TrainError::config(
            "frames",
            "0; a sequence needs at least 1",
        ));
    }
    let mut staged = evogs_io::atomic::StagedFiles::create(dir)?;
    let mut seq = Sequence {
        format,
        count,
        files: Vec::with_capacity(count),
        times: Vec::with_capacity(count),
        gaussians: Vec::with_capacity(count),
        bounds: bounds(&run.canonical.means),
    };
    for k in 0..count {
        let t = if count > 1 {
            k as f32 / (count - 1) as f32
        } else {
            0.0
        };
        let name = format!("frame_{k:04}.{}", format.extension());
        let path = staged.stage(&name);
        let n = export_frame_as(run, t, format, &path).map_err(|e| target_named(&staged, e))?;
        seq.files.push(name);
        seq.times.push(t);
        seq.gaussians.push(n);
    }
    let index = staged.stage("sequence.json");
    write_json(&index, &seq).map_err(|e| target_named(&staged, e))?;
    staged.commit()?;
    Ok(seq)
}

/// A file error about a staged file of `staged`, naming the file it was to become.
fn target_named(staged: &evogs_io::atomic::StagedFiles, e: TrainError) -> TrainError {
    match e {
        TrainError::Io(io) => TrainError::Io(staged.named_as_target(io)),
        TrainError::File { path, problem } => match staged.target_of(&path) {
            Some(target) => TrainError::File {
                path: target,
                problem,
            },
            None => TrainError::File { path, problem },
        },
        e => e,
    }
}

fn bounds(means: &[[f32; 3]]) -> [[f32; 3]; 2] {
    let mut b = [[f32::INFINITY; 3], [f32::NEG_INFINITY; 3]];
    for m in means.iter().filter(|m| m.iter().all(|v| v.is_finite())) {
        for k in 0..3 {
            b[0][k] = b[0][k].min(m[k]);
            b[1][k] = b[1][k].max(m[k]);
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn export_formats_spell_alike() {
        let all = [
            ExportFormat::Ply,
            ExportFormat::CompressedPly,
            ExportFormat::Splat,
        ];
        let names: Vec<String> = all.iter().map(ExportFormat::to_string).collect();
        assert_eq!(names, ExportFormat::VARIANTS);
        for v in all {
            assert_eq!(v.to_string().parse::<ExportFormat>().unwrap(), v);
            assert_eq!(serde_json::to_string(&v).unwrap(), format!("\"{v}\""));
        }
        assert_eq!(
            "tiff".parse::<ExportFormat>().unwrap_err(),
            "unknown export format `tiff`; expected ply, compressed-ply or splat"
        );
    }
}
