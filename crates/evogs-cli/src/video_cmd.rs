//! `evogs video`: a trained run rendered along a camera path into an mp4, a GIF or a folder of
//! PNG frames, optionally beside a second run (`--compare`).

use std::path::{Path, PathBuf};

use crate::progress::Counted;
use anyhow::{Context, Result, bail};
use clap::Args;
use evogs_eval::LoadedRun;
use evogs_eval::render::render_at;
use evogs_io::VideoWriter;
use evogs_video::video::{PathSpec, TimeSpec, plan_frames, side_by_side};

use crate::render::{MAX_PIXELS, resize_camera};
use crate::shared_args::RasterArgs;

/// Arguments of `evogs video`.
#[derive(Debug, Args)]
pub struct VideoArgs {
    /// Run directory written by `evogs train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,

    /// Output: OUT.mp4 (H.264 through an installed ffmpeg, or $EVOGS_FFMPEG), OUT.gif, or a
    /// folder of PNG frames (no extension); written atomically.
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,

    /// Camera path: orbit or spiral (fitted to the training cameras: their mean up vector and
    /// the point nearest to their optical axes), dataset:SPLIT (that split's cameras in time
    /// order, slerp between them), dataset:SPLIT:INDEX (that one camera held still), or a JSON
    /// list of nerfies cameras each with a "time".
    #[arg(
        long,
        default_value = "orbit",
        value_name = "orbit|spiral|dataset:SPLIT[:INDEX]|CAMS.json"
    )]
    pub path: PathSpec,

    /// Frames [default: 60 for orbit, spiral and a still camera, one per camera for the others].
    #[arg(long, allow_negative_numbers = true, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: Option<u32>,

    /// Frames per second.
    #[arg(long, default_value_t = 30.0, value_name = "F")]
    pub fps: f32,

    /// Time: sweep (moves with the camera: over [0, 1] on orbit, spiral and a still camera, the
    /// cameras' own times on the others), T (frozen, "bullet time"), or A:B (evenly from A to B).
    #[arg(
        long,
        default_value = "sweep",
        value_name = "sweep|T|A:B",
        allow_hyphen_values = true
    )]
    pub time: TimeSpec,

    /// Frame size; the path's intrinsics are scaled to it [default: the dataset cameras' size
    /// at the run's resolution].
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(u32, u32)>,

    /// A second run rendered beside the first at the same cameras and times, each labelled with
    /// its directory name.
    #[arg(long, value_name = "RUN_B")]
    pub compare: Option<PathBuf>,

    /// The rasterizer backend.
    #[command(flatten)]
    pub raster: RasterArgs,
}

/// Parses `WxH` with both sides in 1..=16384.
pub fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{text}`: expected WxH, e.g. 400x400"))?;
    let side = |s: &str| -> Result<u32, String> {
        match s.trim().parse::<u32>() {
            Ok(v) if (1..=16384).contains(&v) => Ok(v),
            _ => Err(format!(
                "`{text}`: `{s}` is not a whole number in 1..=16384"
            )),
        }
    };
    Ok((side(w)?, side(h)?))
}

/// What a video command wrote.
#[derive(Debug)]
pub struct VideoReport {
    /// Frames written.
    pub frames: usize,
    /// Frame size (with `--compare`: both runs and the label bar).
    pub width: u32,
    /// Frame size.
    pub height: u32,
    /// The backend that rendered, and why.
    pub backend: String,
}

fn label(run: &Path) -> String {
    run.file_name().map_or_else(
        || run.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Runs `evogs video`.
pub fn run_video(args: &VideoArgs) -> Result<VideoReport> {
    let mut run = LoadedRun::open(&args.run)?;
    let backend = run.use_backend(args.raster.backend)?;
    let mut other = match &args.compare {
        Some(path) => {
            let mut b = LoadedRun::open(path)?;
            b.use_backend(args.raster.backend)?;
            Some(b)
        }
        None => None,
    };
    let frames = plan_frames(&run, &args.path, args.frames.map(|n| n as usize), args.time)?;
    let frames: Vec<_> = frames
        .into_iter()
        .map(|(c, t)| {
            (
                resize_camera(c, args.size.map(|s| s.0), args.size.map(|s| s.1)),
                t,
            )
        })
        .collect();
    let first = frames.first().context("the path has no frames")?.0;
    if first.width as u64 * first.height as u64 > MAX_PIXELS {
        bail!(
            "frame size {}x{} exceeds the limit of {MAX_PIXELS} pixels",
            first.width,
            first.height
        );
    }
    let (width, height) = match other {
        Some(_) => (
            2 * first.width,
            first.height + evogs_video::video::LABEL_BAR,
        ),
        None => (first.width, first.height),
    };
    let mut writer = VideoWriter::create(&args.out, width, height, args.fps)?;
    let labels = [
        label(&args.run),
        args.compare.as_deref().map(label).unwrap_or_default(),
    ];
    let mut progress = Counted::new(frames.len(), "frame")?;
    for (camera, time) in &frames {
        let a = render_at(&mut run, camera, *time)?;
        let image = match other.as_mut() {
            Some(b) => {
                let b = render_at(b, camera, *time)?;
                side_by_side(&a, &b, [&labels[0], &labels[1]])
            }
            None => a,
        };
        writer.push(&image)?;
        progress.inc();
    }
    progress.finish();
    let count = writer.finish()?;
    Ok(VideoReport {
        frames: count,
        width,
        height,
        backend: backend.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("400x300").unwrap(), (400, 300));
        assert!(parse_size("400").unwrap_err().contains("WxH"));
        assert!(parse_size("0x3").unwrap_err().contains("`0`"));
    }
}
