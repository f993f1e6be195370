//! Videos of a run: the camera and time of every frame ([`plan_frames`]), the time modes
//! ([`TimeSpec`]), and two runs side by side with labels ([`side_by_side`]).
//!
//! Paths ([`PathSpec`], geometry in [`crate::camera_path`]): `orbit` and `spiral` are fitted to
//! the run's training cameras and use the first one's intrinsics; `dataset:SPLIT` replays that
//! split's cameras in time order (slerp between them; as many frames as cameras by default, so
//! each frame is a dataset camera at its time); `dataset:SPLIT:INDEX` holds that one dataset
//! camera still (D-3DGS's `render.py --mode time`); a JSON file is a list of nerfies cameras with
//! times (`evogs_io::read_camera_path`), replayed the same way.
//!
//! Times: `sweep` moves time with the camera (orbit, spiral and a still camera: evenly over the
//! training range [0, 1]; replays: the interpolated keyframe times), `T` freezes it ("bullet time"), `A:B` runs
//! evenly from A to B (A ≤ B, both finite).
//!
//! What it is not: a renderer ([`evogs_eval::render::render_at`] renders each frame) or an encoder
//! (`evogs_io::VideoWriter`).

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use evogs_eval::LoadedRun;
use evogs_io::{ImageRgb, Split, read_camera_path};
use evogs_train::TrainError;
use splat_raster::Camera;

use crate::camera_path::{
    CameraSpec, Keyframes, SceneFit, dataset_camera, orbit, spiral, split_cameras,
};

/// Frames of an orbit or a spiral when no count is given.
pub const DEFAULT_FRAMES: usize = 60;

/// Height in pixels of the label bar above side-by-side frames.
pub const LABEL_BAR: u32 = 20;

/// The camera path of a video.
#[derive(Clone, Debug, PartialEq)]
pub enum PathSpec {
    /// A circle about the fitted axis.
    Orbit,
    /// A helix over the training cameras' heights.
    Spiral,
    /// A split's cameras in time order.
    Dataset(Split),
    /// One camera of a split, held still.
    Still {
        /// The split.
        split: Split,
        /// The camera's index in file order.
        index: usize,
    },
    /// A JSON list of nerfies cameras with times.
    File(PathBuf),
}

impl FromStr for PathSpec {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Ok(match text {
            "orbit" => Self::Orbit,
            "spiral" => Self::Spiral,
            _ => match text.strip_prefix("dataset:") {
                Some(rest) if rest.contains(':') => match text.parse::<CameraSpec>()? {
                    CameraSpec::Dataset { split, index } => Self::Still { split, index },
                    CameraSpec::File(_) => unreachable!("starts with dataset:"),
                },
                Some(split) => Self::Dataset(split.parse().map_err(|e| format!("`{text}`: {e}"))?),
                None => Self::File(PathBuf::from(text)),
            },
        })
    }
}

/// How time moves during a video.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeSpec {
    /// With the camera (see the module docs).
    Sweep,
    /// Fixed.
    Fixed(f32),
    /// Evenly from the first to the second (first ≤ second).
    Range(f32, f32),
}

impl FromStr for TimeSpec {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let number = |s: &str| -> Result<f32, String> {
            let v: f32 = s
                .trim()
                .parse()
                .map_err(|_| format!("`{s}` is not a number"))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("{v} is not a finite number"))
            }
        };
        if text == "sweep" {
            return Ok(Self::Sweep);
        }
        match text.split_once(':') {
            Some((a, b)) => {
                let (a, b) = (number(a)?, number(b)?);
                if a > b {
                    return Err(format!(
                        "range {a}:{b} is reversed (the start exceeds the end)"
                    ));
                }
                Ok(Self::Range(a, b))
            }
            None => Ok(Self::Fixed(number(text)?)),
        }
    }
}

impl fmt::Display for TimeSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Sweep => f.write_str("sweep"),
            Self::Fixed(t) => write!(f, "{t}"),
            Self::Range(a, b) => write!(f, "{a}:{b}"),
        }
    }
}

/// `k / (n − 1)`, 0 for a single frame.
fn fraction(k: usize, n: usize) -> f32 {
    if n > 1 {
        k as f32 / (n - 1) as f32
    } else {
        0.0
    }
}

/// The camera and time of each frame of a video of `run` (see the module docs); `frames` ≥ 1
/// when given.
pub fn plan_frames(
    run: &LoadedRun,
    path: &PathSpec,
    frames: Option<usize>,
    time: TimeSpec,
) -> Result<Vec<(Camera, f32)>, TrainError> {
    if frames == Some(0) {
        return Err(TrainError::config("frames", "0; a video needs at least 1"));
    }
    let path_frames: Vec<(Camera, f32)> = match path {
        PathSpec::Orbit | PathSpec::Spiral => {
            let cameras: Vec<Camera> = split_cameras(run, Split::Train)?
                .into_iter()
                .map(|(c, _)| c)
                .collect();
            let fit = SceneFit::fit(&cameras)?;
            let n = frames.unwrap_or(DEFAULT_FRAMES);
            let path = if *path == PathSpec::Orbit {
                orbit(&fit, &cameras[0], n)
            } else {
                spiral(&fit, &cameras[0], n)
            };
            path.into_iter()
                .enumerate()
                .map(|(k, c)| (c, fraction(k, n)))
                .collect()
        }
        PathSpec::Still { split, index } => {
            let (camera, _) = dataset_camera(run, *split, *index)?;
            let n = frames.unwrap_or(DEFAULT_FRAMES);
            (0..n).map(|k| (camera, fraction(k, n))).collect()
        }
        PathSpec::Dataset(split) => {
            let keys = Keyframes::new(split_cameras(run, *split)?)?;
            keys.sample(frames.unwrap_or(keys.cameras().len()))
        }
        PathSpec::File(file) => {
            if !file.is_file() {
                return Err(TrainError::file(
                    file,
                    "no such camera-path file (--path takes orbit, spiral, dataset:SPLIT, \
                     dataset:SPLIT:INDEX or a JSON list of cameras)",
                ));
            }
            let cameras = read_camera_path(file)?
                .into_iter()
                .map(|c| (c.info.camera, c.time))
                .collect();
            let keys =
                Keyframes::new(cameras).map_err(|e| TrainError::file(file, e.to_string()))?;
            keys.sample(frames.unwrap_or(keys.cameras().len()))
        }
    };
    let n = path_frames.len();
    Ok(path_frames
        .into_iter()
        .enumerate()
        .map(|(k, (camera, t))| {
            let t = match time {
                TimeSpec::Sweep => t,
                TimeSpec::Fixed(t) => t,
                TimeSpec::Range(a, b) => a + (b - a) * fraction(k, n),
            };
            (camera, t)
        })
        .collect())
}

/// Two frames of one size side by side, `a` left and `b` right, under a black bar of
/// [`LABEL_BAR`] pixels with each one's label in white (the system's sans-serif font; without
/// one, the bar stays empty). The frames' pixels are copied exactly.
pub fn side_by_side(a: &ImageRgb, b: &ImageRgb, labels: [&str; 2]) -> ImageRgb {
    let (w, h) = (a.width, a.height);
    let mut out = ImageRgb::filled(2 * w, h + LABEL_BAR, [0.0; 3]);
    for (side, img) in [a, b].into_iter().enumerate() {
        for y in 0..h.min(img.height) as usize {
            let src = &img.pixels[y * img.width as usize..][..w.min(img.width) as usize];
            let at = (y + LABEL_BAR as usize) * 2 * w as usize + side * w as usize;
            out.pixels[at..at + src.len()].copy_from_slice(src);
        }
    }
    let mut bar = vec![0u8; (2 * w * LABEL_BAR * 3) as usize];
    if draw_labels(&mut bar, 2 * w, labels).is_ok() {
        for (p, rgb) in out.pixels.iter_mut().zip(bar.chunks_exact(3)) {
            *p = [0, 1, 2].map(|c| f32::from(rgb[c]) / 255.0);
        }
    }
    out
}

fn draw_labels(buf: &mut [u8], width: u32, labels: [&str; 2]) -> Result<(), String> {
    use plotters::prelude::*;
    use plotters::style::text_anchor::{HPos, Pos, VPos};
    let root = BitMapBackend::with_buffer(buf, (width, LABEL_BAR)).into_drawing_area();
    let style = ("sans-serif", (LABEL_BAR - 4) as f64)
        .into_font()
        .color(&WHITE)
        .pos(Pos::new(HPos::Center, VPos::Center));
    for (side, label) in labels.iter().enumerate() {
        let x = (width / 4 * (2 * side as u32 + 1)) as i32;
        root.draw_text(label, &style, (x, (LABEL_BAR / 2) as i32))
            .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_specs_parse_and_refuse_bad_ranges() {
        assert_eq!("sweep".parse::<TimeSpec>().unwrap(), TimeSpec::Sweep);
        assert_eq!("0.5".parse::<TimeSpec>().unwrap(), TimeSpec::Fixed(0.5));
        assert_eq!(
            "-1:2".parse::<TimeSpec>().unwrap(),
            TimeSpec::Range(-1.0, 2.0)
        );
        let e = "0.8:0.2".parse::<TimeSpec>().unwrap_err();
        assert!(e.contains("reversed"), "{e}");
        let e = "0:inf".parse::<TimeSpec>().unwrap_err();
        assert!(e.contains("not a finite"), "{e}");
        let e = "NaN".parse::<TimeSpec>().unwrap_err();
        assert!(e.contains("not a finite"), "{e}");
        let e = "soon".parse::<TimeSpec>().unwrap_err();
        assert!(e.contains("not a number"), "{e}");
    }

    #[test]
    fn path_specs_parse() {
        assert_eq!("orbit".parse::<PathSpec>().unwrap(), PathSpec::Orbit);
        assert_eq!(
            "dataset:val".parse::<PathSpec>().unwrap(),
            PathSpec::Dataset(Split::Val)
        );
        assert_eq!(
            "p.json".parse::<PathSpec>().unwrap(),
            PathSpec::File("p.json".into())
        );
        assert_eq!(
            "dataset:test:4".parse::<PathSpec>().unwrap(),
            PathSpec::Still {
                split: Split::Test,
                index: 4
            }
        );
        let e = "dataset:dev".parse::<PathSpec>().unwrap_err();
        assert!(e.contains("unknown split `dev`"), "{e}");
        let e = "dataset:dev:1".parse::<PathSpec>().unwrap_err();
        assert!(e.contains("unknown split `dev`"), "{e}");
        let e = "dataset:test:x".parse::<PathSpec>().unwrap_err();
        assert!(e.contains("not a whole number"), "{e}");
    }

    #[test]
    fn side_by_side_copies_both_frames_below_the_bar() {
        let a = ImageRgb::filled(5, 3, [0.25, 0.5, 0.75]);
        let mut b = ImageRgb::filled(5, 3, [1.0, 0.0, 0.0]);
        b.pixels[7] = [0.0, 1.0, 0.0];
        let out = side_by_side(&a, &b, ["a", "b"]);
        assert_eq!((out.width, out.height), (10, 3 + LABEL_BAR));
        for y in 0..3 {
            for x in 0..5 {
                assert_eq!(out.get(x, y + LABEL_BAR), a.get(x, y));
                assert_eq!(out.get(x + 5, y + LABEL_BAR), b.get(x, y));
            }
        }
    }
}
