//! Stage 1: the frames. A video is decoded by ffmpeg into `frame_NNNNN.png` (numbered from 0 in
//! clip order, evenly spaced over the clip when `--fps` or `--max-frames` thins them); an image
//! folder is copied (or scaled by ffmpeg with `--downscale`), keeping the names.

use std::path::{Path, PathBuf};

use crate::tools::{FFMPEG, FFPROBE, arg, image_files, last_message, run_logged};
use crate::{PrepareError, PrepareRequest, Source};

/// Fewer frames than this cannot make a reconstruction worth training on.
pub const MIN_FRAMES: usize = 3;

/// The frame file name for index `i` (what `--time-from name` and `order` both read).
pub fn frame_name(i: usize) -> String {
    format!("frame_{i:05}.png")
}

/// The clip's duration in seconds and its frame rate, when ffprobe can tell.
fn probe(video: &Path) -> (Option<f64>, Option<f64>) {
    let out = std::process::Command::new(FFPROBE.program)
        .args([
            "-v",
            "error",
            "-select_streams",
            "v:0",
            "-show_entries",
            "format=duration:stream=avg_frame_rate",
            "-of",
            "default=noprint_wrappers=1",
        ])
        .arg(video)
        .stdin(std::process::Stdio::null())
        .output();
    let Ok(out) = out else {
        return (None, None);
    };
    let text = String::from_utf8_lossy(&out.stdout);
    let mut duration = None;
    let mut rate = None;
    for line in text.lines() {
        if let Some(v) = line.strip_prefix("duration=") {
            duration = v.trim().parse::<f64>().ok().filter(|d| *d > 0.0);
        } else if let Some(v) = line.strip_prefix("avg_frame_rate=") {
            let mut parts = v.trim().split('/');
            let num: Option<f64> = parts.next().and_then(|n| n.parse().ok());
            let den: f64 = parts.next().and_then(|d| d.parse().ok()).unwrap_or(1.0);
            rate = num.map(|n| n / den).filter(|r| r.is_finite() && *r > 0.0);
        }
    }
    (duration, rate)
}

/// The ffmpeg scale filter for a downscale factor (even sizes are not needed for PNG).
fn scale_filter(downscale: f64) -> Option<String> {
    (downscale != 1.0)
        .then(|| format!("scale=trunc(iw/{downscale}+0.5):trunc(ih/{downscale}+0.5):flags=area"))
}

/// Decodes `video` into `frames/`; returns the frame files and the sampling rate used.
fn from_video(
    request: &PrepareRequest,
    video: &Path,
    frames: &Path,
    log: &Path,
) -> Result<(Vec<PathBuf>, Option<f64>), PrepareError> {
    let (duration, native) = probe(video);
    // Frames per second to sample: the requested rate (or the clip's), lowered so that the
    // whole clip fits in max_frames.
    let wanted = request.fps.or(native);
    let fps = match (wanted, duration) {
        (Some(f), Some(d)) if f * d > request.max_frames as f64 => {
            Some(request.max_frames as f64 / d)
        }
        _ => request.fps,
    };
    let mut filters = Vec::new();
    if let Some(f) = fps {
        filters.push(format!("fps={f}"));
    }
    filters.extend(scale_filter(request.downscale));
    let mut args: Vec<String> = vec!["-nostdin".into(), "-hide_banner".into(), "-i".into()];
    args.push(arg(video));
    if !filters.is_empty() {
        args.extend(["-vf".into(), filters.join(",")]);
    }
    args.extend([
        "-frames:v".into(),
        request.max_frames.to_string(),
        "-start_number".into(),
        "0".into(),
        arg(&frames.join("frame_%05d.png")),
    ]);
    let ran = run_logged(&FFMPEG, &args, log, video, "ffmpeg frame extraction");
    let files = image_files(frames)?;
    if files.is_empty() {
        return Err(PrepareError::input(
            video,
            format!(
                "no decodable video frames (ffmpeg: {})",
                last_message(log).trim_start_matches(&format!("{}: ", video.display()))
            ),
        ));
    }
    ran?;
    Ok((files, fps))
}

/// Copies (or scales) the images of `dir` into `frames/`, keeping their names (scaled ones
/// become `.png`).
fn from_images(
    request: &PrepareRequest,
    dir: &Path,
    frames: &Path,
    log: &Path,
) -> Result<Vec<PathBuf>, PrepareError> {
    if !dir.is_dir() {
        return Err(PrepareError::input(dir, "is not a folder"));
    }
    let sources = image_files(dir)?;
    if sources.len() < MIN_FRAMES {
        return Err(PrepareError::input(
            dir,
            format!(
                "{} image file(s) (.png/.jpg/.jpeg); a reconstruction needs at least {MIN_FRAMES}",
                sources.len()
            ),
        ));
    }
    let mut out = Vec::with_capacity(sources.len());
    std::fs::write(log, "").map_err(|e| PrepareError::io(log, e))?;
    for source in sources.iter().take(request.max_frames) {
        let name = source.file_name().unwrap_or_default();
        match scale_filter(request.downscale) {
            None => {
                let target = frames.join(name);
                std::fs::copy(source, &target).map_err(|e| PrepareError::io(source, e))?;
                out.push(target);
            }
            Some(filter) => {
                let target = frames.join(Path::new(name).with_extension("png"));
                let args = vec![
                    "-nostdin".into(),
                    "-hide_banner".into(),
                    "-i".into(),
                    arg(source),
                    "-vf".into(),
                    filter,
                    "-frames:v".into(),
                    "1".into(),
                    arg(&target),
                ];
                let one = log.with_extension("one.log");
                run_logged(&FFMPEG, &args, &one, source, "ffmpeg scaling")?;
                let text = std::fs::read_to_string(&one).unwrap_or_default();
                let mut all = std::fs::read_to_string(log).unwrap_or_default();
                all.push_str(&text);
                std::fs::write(log, all).map_err(|e| PrepareError::io(log, e))?;
                std::fs::remove_file(&one).map_err(|e| PrepareError::io(&one, e))?;
                out.push(target);
            }
        }
    }
    Ok(out)
}

/// The frames of the request's source in `frames/` (created), and the sampling rate of a video.
pub fn extract(
    request: &PrepareRequest,
    frames: &Path,
    log: &Path,
) -> Result<(Vec<PathBuf>, Option<f64>), PrepareError> {
    std::fs::create_dir_all(frames).map_err(|e| PrepareError::io(frames, e))?;
    let (files, fps) = match &request.source {
        Source::Video(video) => from_video(request, video, frames, log)?,
        Source::Images(dir) => (from_images(request, dir, frames, log)?, None),
    };
    if files.len() < MIN_FRAMES {
        return Err(PrepareError::input(
            request.source.path(),
            format!(
                "{} frame(s) extracted; a reconstruction needs at least {MIN_FRAMES} (raise \
                 --fps or --max-frames)",
                files.len()
            ),
        ));
    }
    Ok((files, fps))
}
