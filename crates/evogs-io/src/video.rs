//! Video output: frames (f32 RGB, as rendered) to an animated GIF, an H.264 mp4, or a folder of
//! PNG frames, chosen by the output's name, each written atomically.
//!
//! - `.gif`: the `gif` crate's encoder (the one the `image` crate uses), a palette of up to 256
//!   colours per frame chosen by NeuQuant; frame delays are whole hundredths of a second (the
//!   GIF unit), so 30 fps plays at 100/3 ≈ 33 fps; loops forever.
//! - `.mp4`: frames piped as raw RGB to an installed `ffmpeg` (`$EVOGS_FFMPEG`, else `ffmpeg`
//!   on `PATH`): libx264, yuv420p, CRF 18; odd sizes are padded by one black row or column
//!   (yuv420p needs even sides). Without ffmpeg: a one-line error saying so.
//! - no extension (a folder): `frame_0000.png`, … (8 bits per channel, [`crate::save_png`]).
//!
//! Atomic: the GIF and the mp4 are written to a temporary file beside the target and renamed
//! over it by [`VideoWriter::finish`]; the folder is written as a temporary folder and renamed
//! into place (an existing folder is replaced only then). Dropped without `finish` (an error while
//! rendering), nothing is left behind and an existing output is untouched.
//!
//! What it is not: a renderer or a camera path (`evogs-train`).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

use crate::IoError;
use crate::atomic::{AtomicFile, parent_dir, set_output_mode, temp_error};
use crate::image_io::{ImageRgb, save_png, to_u8};

/// The environment variable naming the ffmpeg executable (default `ffmpeg` on `PATH`).
pub const FFMPEG_ENV: &str = "EVOGS_FFMPEG";

/// The kinds of video output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VideoFormat {
    /// Animated GIF.
    Gif,
    /// H.264 in mp4, through ffmpeg.
    Mp4,
    /// A folder of PNG frames.
    Frames,
}

impl VideoFormat {
    /// The format a path asks for: `.gif`, `.mp4`, or a folder (no extension); any other
    /// extension is an error naming the path.
    pub fn of_path(path: &Path) -> Result<Self, IoError> {
        match path.extension().and_then(|e| e.to_str()) {
            None => Ok(Self::Frames),
            Some(e) if e.eq_ignore_ascii_case("gif") => Ok(Self::Gif),
            Some(e) if e.eq_ignore_ascii_case("mp4") => Ok(Self::Mp4),
            Some(e) => Err(IoError::InvalidData {
                path: path.to_path_buf(),
                problem: format!(
                    "unknown video extension `.{e}`: write .mp4, .gif, or a folder (no extension)"
                ),
            }),
        }
    }
}

/// The ffmpeg executable: `$EVOGS_FFMPEG`, else `ffmpeg`.
pub fn ffmpeg_program() -> PathBuf {
    std::env::var_os(FFMPEG_ENV).map_or_else(|| PathBuf::from("ffmpeg"), PathBuf::from)
}

enum Sink {
    Gif {
        encoder: Option<gif::Encoder<AtomicFile>>,
    },
    Mp4 {
        child: Child,
        stdin: Option<ChildStdin>,
        temp: Option<tempfile::TempPath>,
        padded: (u32, u32),
    },
    Frames {
        temp: Option<tempfile::TempDir>,
    },
}

/// Writes frames of one size to a video file or folder (see the module docs).
pub struct VideoWriter {
    out: PathBuf,
    width: u32,
    height: u32,
    fps: f32,
    count: usize,
    sink: Sink,
}

fn invalid(path: &Path, problem: impl Into<String>) -> IoError {
    IoError::InvalidData {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

impl VideoWriter {
    /// Starts writing `out` (format from its name) for frames of `width × height` at `fps`
    /// frames per second. Fails now, before any frame is rendered, when the output's directory
    /// is not writable or ffmpeg is needed and missing.
    pub fn create(out: &Path, width: u32, height: u32, fps: f32) -> Result<Self, IoError> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(invalid(out, format!("fps {fps} is not a positive number")));
        }
        if width == 0 || height == 0 || width > u16::MAX as u32 || height > u16::MAX as u32 {
            return Err(invalid(out, format!("frame size {width}x{height}")));
        }
        let sink = match VideoFormat::of_path(out)? {
            VideoFormat::Gif => {
                let file = AtomicFile::create(out)?;
                let mut encoder = gif::Encoder::new(file, width as u16, height as u16, &[])
                    .map_err(|e| invalid(out, e.to_string()))?;
                encoder
                    .set_repeat(gif::Repeat::Infinite)
                    .map_err(|e| invalid(out, e.to_string()))?;
                Sink::Gif {
                    encoder: Some(encoder),
                }
            }
            VideoFormat::Mp4 => start_ffmpeg(out, width, height, fps)?,
            VideoFormat::Frames => {
                if out.exists() && !out.is_dir() {
                    return Err(invalid(out, "exists and is not a folder"));
                }
                let temp = tempfile::Builder::new()
                    .prefix(".evogs-tmp-")
                    .tempdir_in(parent_dir(out))
                    .map_err(|e| temp_error(out, parent_dir(out), &e))?;
                Sink::Frames { temp: Some(temp) }
            }
        };
        Ok(Self {
            out: out.to_path_buf(),
            width,
            height,
            fps,
            count: 0,
            sink,
        })
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.count
    }

    /// Appends a frame (values clamped to [0, 1], 8 bits per channel as [`to_u8`]).
    pub fn push(&mut self, frame: &ImageRgb) -> Result<(), IoError> {
        if (frame.width, frame.height) != (self.width, self.height)
            || frame.pixels.len() != self.width as usize * self.height as usize
        {
            return Err(invalid(
                &self.out,
                format!(
                    "frame {} is {}x{}, the video {}x{}",
                    self.count, frame.width, frame.height, self.width, self.height
                ),
            ));
        }
        let out = &self.out;
        match &mut self.sink {
            Sink::Gif { encoder } => {
                let rgb = rgb_bytes(frame, frame.width, frame.height);
                // NeuQuant speed 10: the `image` crate's default for GIF.
                let mut f =
                    gif::Frame::from_rgb_speed(self.width as u16, self.height as u16, &rgb, 10);
                f.delay = gif_delay(self.fps);
                encoder
                    .as_mut()
                    .ok_or_else(|| invalid(out, "the GIF is already finished"))?
                    .write_frame(&f)
                    .map_err(|e| gif_error(out, e))?;
            }
            Sink::Mp4 { stdin, padded, .. } => {
                let rgb = rgb_bytes(frame, padded.0, padded.1);
                stdin
                    .as_mut()
                    .ok_or_else(|| invalid(out, "the video is already finished"))?
                    .write_all(&rgb)
                    .map_err(|e| invalid(out, format!("ffmpeg stopped reading frames: {e}")))?;
            }
            Sink::Frames { temp } => {
                let dir = temp
                    .as_ref()
                    .ok_or_else(|| invalid(out, "the folder is already finished"))?;
                save_png(&dir.path().join(frame_name(self.count)), frame)?;
            }
        }
        self.count += 1;
        Ok(())
    }

    /// Finishes the video and moves it into place; returns the number of frames. At least one
    /// frame is needed.
    pub fn finish(mut self) -> Result<usize, IoError> {
        if self.count == 0 {
            return Err(invalid(&self.out, "no frames"));
        }
        let out = self.out.clone();
        match &mut self.sink {
            Sink::Gif { encoder } => {
                let encoder = encoder
                    .take()
                    .ok_or_else(|| invalid(&out, "finished twice"))?;
                let file = encoder.into_inner().map_err(|e| gif_error(&out, e))?;
                file.commit()?;
            }
            Sink::Mp4 {
                child, stdin, temp, ..
            } => {
                drop(stdin.take());
                wait_ffmpeg(child, &out)?;
                let temp = temp.take().ok_or_else(|| invalid(&out, "finished twice"))?;
                let file = std::fs::File::open(&temp).map_err(|e| IoError::io(&out, e))?;
                set_output_mode(&file, &out).map_err(|e| IoError::io(&out, e))?;
                temp.persist(&out).map_err(|e| IoError::io(&out, e.error))?;
            }
            Sink::Frames { temp } => {
                let dir = temp.take().ok_or_else(|| invalid(&out, "finished twice"))?;
                replace_folder(dir, &out)?;
            }
        }
        Ok(self.count)
    }
}

impl Drop for VideoWriter {
    fn drop(&mut self) {
        // An unfinished mp4: stop ffmpeg; its temporary output is removed with the TempPath.
        if let Sink::Mp4 { child, stdin, .. } = &mut self.sink {
            drop(stdin.take());
            if child.try_wait().ok().flatten().is_none() {
                let _ = child.kill();
                let _ = child.wait();
            }
        }
    }
}

/// The file name of frame `k` in a frames folder: `frame_0000.png`, …
pub fn frame_name(k: usize) -> String {
    format!("frame_{k:04}.png")
}

/// GIF delay in hundredths of a second for `fps`: `round(100 / fps)`, at least 1.
pub fn gif_delay(fps: f32) -> u16 {
    (100.0 / fps).round().clamp(1.0, u16::MAX as f32) as u16
}

/// 8-bit RGB bytes of `frame` placed at the top left of a `width × height` black canvas.
fn rgb_bytes(frame: &ImageRgb, width: u32, height: u32) -> Vec<u8> {
    let mut bytes = vec![0u8; width as usize * height as usize * 3];
    for y in 0..frame.height as usize {
        for x in 0..frame.width as usize {
            let p = frame.pixels[y * frame.width as usize + x];
            let at = (y * width as usize + x) * 3;
            for c in 0..3 {
                bytes[at + c] = to_u8(p[c]);
            }
        }
    }
    bytes
}

fn gif_error(out: &Path, e: gif::EncodingError) -> IoError {
    match e {
        gif::EncodingError::Io(e) => IoError::io(out, e),
        other => invalid(out, other.to_string()),
    }
}

fn start_ffmpeg(out: &Path, width: u32, height: u32, fps: f32) -> Result<Sink, IoError> {
    let temp = tempfile::Builder::new()
        .prefix(".evogs-tmp-")
        .suffix(".mp4")
        .tempfile_in(parent_dir(out))
        .map_err(|e| temp_error(out, parent_dir(out), &e))?
        .into_temp_path();
    let padded = (width.next_multiple_of(2), height.next_multiple_of(2));
    let program = ffmpeg_program();
    let spawned = Command::new(&program)
        .args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y"])
        .args(["-f", "rawvideo", "-pix_fmt", "rgb24"])
        .args(["-s", &format!("{}x{}", padded.0, padded.1)])
        .args(["-framerate", &fps.to_string(), "-i", "pipe:0"])
        .args(["-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "18"])
        .args(["-movflags", "+faststart", "-f", "mp4"])
        .arg(temp.as_os_str())
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn();
    let mut child = match spawned {
        Ok(child) => child,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(invalid(
                out,
                format!(
                    "mp4 needs ffmpeg, and `{}` was not found (install ffmpeg, set {FFMPEG_ENV}, \
                     or write a .gif or a folder of PNG frames)",
                    program.display()
                ),
            ));
        }
        Err(e) => {
            return Err(invalid(
                out,
                format!("cannot start `{}`: {e}", program.display()),
            ));
        }
    };
    let stdin = child.stdin.take();
    Ok(Sink::Mp4 {
        child,
        stdin,
        temp: Some(temp),
        padded,
    })
}

fn wait_ffmpeg(child: &mut Child, out: &Path) -> Result<(), IoError> {
    let mut message = String::new();
    if let Some(mut err) = child.stderr.take() {
        use std::io::Read;
        let _ = err.read_to_string(&mut message);
    }
    let status = child.wait().map_err(|e| IoError::io(out, e))?;
    if !status.success() {
        let last = message.lines().rev().find(|l| !l.trim().is_empty());
        return Err(invalid(
            out,
            format!(
                "ffmpeg failed ({status}): {}",
                last.unwrap_or("no message").trim()
            ),
        ));
    }
    Ok(())
}

/// Renames the finished temporary folder to `out`; an existing folder at `out` is moved aside
/// first and removed afterwards.
fn replace_folder(dir: tempfile::TempDir, out: &Path) -> Result<(), IoError> {
    let aside = if out.exists() {
        let aside = tempfile::Builder::new()
            .prefix(".evogs-old-")
            .tempdir_in(parent_dir(out))
            .map_err(|e| temp_error(out, parent_dir(out), &e))?;
        let aside = aside.keep();
        // Renaming a folder over an empty one replaces it.
        std::fs::rename(out, &aside).map_err(|e| IoError::io(out, e))?;
        Some(aside)
    } else {
        None
    };
    let path = dir.keep();
    if let Err(e) = std::fs::rename(&path, out) {
        if let Some(aside) = &aside {
            let _ = std::fs::rename(aside, out);
        }
        let _ = std::fs::remove_dir_all(&path);
        return Err(IoError::io(out, e));
    }
    if let Some(aside) = aside {
        let _ = std::fs::remove_dir_all(aside);
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Temporary folders are created private (0700).
        let _ = std::fs::set_permissions(out, std::fs::Permissions::from_mode(0o755));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(w: u32, h: u32, v: f32) -> ImageRgb {
        ImageRgb::filled(w, h, [v, 0.5, 1.0 - v])
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn formats_follow_the_extension() {
        assert_eq!(
            VideoFormat::of_path(Path::new("a.GIF")).unwrap(),
            VideoFormat::Gif
        );
        assert_eq!(
            VideoFormat::of_path(Path::new("a.mp4")).unwrap(),
            VideoFormat::Mp4
        );
        assert_eq!(
            VideoFormat::of_path(Path::new("out/frames")).unwrap(),
            VideoFormat::Frames
        );
        let e = VideoFormat::of_path(Path::new("a.avi"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("a.avi") && e.contains(".avi"), "{e}");
        assert_eq!(gif_delay(30.0), 3);
        assert_eq!(gif_delay(0.5), 200);
    }

    #[test]
    fn gif_frames_decode_to_the_written_colours() {
        use image::AnimationDecoder;
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("v.gif");
        let mut w = VideoWriter::create(&out, 6, 4, 10.0).unwrap();
        for k in 0..3 {
            w.push(&frame(6, 4, k as f32 / 2.0)).unwrap();
        }
        assert_eq!(w.finish().unwrap(), 3);
        let file = std::io::BufReader::new(std::fs::File::open(&out).unwrap());
        let frames = image::codecs::gif::GifDecoder::new(file)
            .unwrap()
            .into_frames()
            .collect_frames()
            .unwrap();
        assert_eq!(frames.len(), 3);
        for (k, f) in frames.iter().enumerate() {
            let p = f.buffer().get_pixel(5, 3).0;
            let expected = [to_u8(k as f32 / 2.0), 128, to_u8(1.0 - k as f32 / 2.0)];
            for c in 0..3 {
                assert!(
                    (p[c] as i32 - expected[c] as i32).abs() <= 2,
                    "{p:?} {expected:?}"
                );
            }
            assert_eq!(f.delay().numer_denom_ms(), (100, 1));
        }
        assert_eq!(entries(dir.path()), ["v.gif"]);
    }

    #[test]
    fn unfinished_or_failed_outputs_leave_nothing_and_keep_the_old_one() {
        let dir = tempfile::tempdir().unwrap();
        let gif = dir.path().join("v.gif");
        std::fs::write(&gif, b"old").unwrap();
        {
            let mut w = VideoWriter::create(&gif, 4, 4, 10.0).unwrap();
            w.push(&frame(4, 4, 0.2)).unwrap();
            // A frame of the wrong size is refused; the writer is then dropped unfinished.
            let e = w.push(&frame(3, 4, 0.2)).unwrap_err().to_string();
            assert!(e.contains("frame 1 is 3x4"), "{e}");
        }
        let folder = dir.path().join("frames");
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(folder.join("keep.txt"), b"old").unwrap();
        {
            let mut w = VideoWriter::create(&folder, 4, 4, 10.0).unwrap();
            w.push(&frame(4, 4, 0.2)).unwrap();
        }
        assert_eq!(std::fs::read(&gif).unwrap(), b"old");
        assert_eq!(entries(&folder), ["keep.txt"]);
        assert_eq!(entries(dir.path()), ["frames", "v.gif"]);
        // Finished, the folder is replaced whole.
        let mut w = VideoWriter::create(&folder, 4, 4, 10.0).unwrap();
        w.push(&frame(4, 4, 0.2)).unwrap();
        w.push(&frame(4, 4, 0.4)).unwrap();
        assert_eq!(w.finish().unwrap(), 2);
        assert_eq!(entries(&folder), ["frame_0000.png", "frame_0001.png"]);
        assert_eq!(entries(dir.path()), ["frames", "v.gif"]);
        // No frames: refused, nothing written.
        let empty = dir.path().join("e.gif");
        let e = VideoWriter::create(&empty, 4, 4, 10.0).unwrap().finish();
        assert!(e.unwrap_err().to_string().contains("no frames"));
        assert!(!empty.exists());
    }

    #[test]
    fn unwritable_outputs_fail_before_any_frame() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["missing/v.gif", "missing/v.mp4", "missing/frames"] {
            let out = dir.path().join(name);
            let e = VideoWriter::create(&out, 4, 4, 10.0)
                .err()
                .unwrap()
                .to_string();
            assert!(e.contains("missing"), "{e}");
        }
        let e = VideoWriter::create(&dir.path().join("v.gif"), 4, 4, f32::NAN)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("fps NaN"), "{e}");
    }
}
