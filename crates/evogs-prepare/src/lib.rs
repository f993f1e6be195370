//! `evogs-prepare`: a video or an image sequence in, a COLMAP dataset that `evogs train` loads
//! out, with each frame's time in the clip (`times.json`).
//!
//! What it is: the `evogs prepare` pipeline, running external programs on the CPU:
//!
//! | stage | program | what it does |
//! |---|---|---|
//! | 1 frames | `ffmpeg` | decodes the clip into `frame_NNNNN.png` (all frames, or `--fps`, at most `--max-frames` spread over the clip; `--downscale`), or copies an image folder |
//! | 2 features | `colmap feature_extractor` | SIFT on the CPU, one shared `SIMPLE_RADIAL` camera |
//! | 3 matching | `colmap sequential_matcher` | each frame against the next 10 (`--matcher exhaustive`: every pair) |
//! | 4 mapping | `colmap mapper` | incremental SfM; the largest model is kept and its registered frames counted |
//! | 5 undistortion | `colmap image_undistorter` | when the camera has distortion: pinhole images and cameras for the pinhole rasterizer |
//! | 6 dataset | — | `DIR/images/`, `DIR/sparse/0/`, `DIR/times.json` (each frame's time in the clip, `i / (n − 1)` over the `n` frames extracted, so frames COLMAP drops do not move the others), `DIR/logs/`, `DIR/prepare.json`, read back with `evogs-io` |
//!
//! Everything is built in a temporary folder beside `DIR` and renamed to `DIR` at the end, so a
//! failure leaves no dataset behind; each stage's output is kept in `DIR/logs/<stage>.log`, and
//! after a failure in `DIR.logs/` ([`failed_logs_dir`]), named in the error.
//!
//! What it is not: a COLMAP binding or a GPU pipeline. The programs come from the Debian
//! packages `ffmpeg` and `colmap`; a missing one stops with one line naming the package.

mod error;
pub mod frames;
pub mod sfm;
pub mod tools;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use splat_core::one_word::{OneWord, unknown_message};

pub use error::PrepareError;

/// What to read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    /// A video file ffmpeg can decode.
    Video(PathBuf),
    /// A folder of `.png` / `.jpg` images, in name order.
    Images(PathBuf),
}

impl Source {
    /// The file or folder.
    pub fn path(&self) -> &Path {
        match self {
            Self::Video(p) | Self::Images(p) => p,
        }
    }
}

/// Which frame pairs COLMAP matches, spelled `sequential` or `exhaustive`.
#[derive(strum::Display, strum::EnumString, strum::IntoStaticStr, strum::VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = String, parse_err_fn = unknown_message::<Self>)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Matcher {
    /// Each frame against the next 10 (a video or an ordered sequence).
    #[default]
    Sequential,
    /// Every pair (unordered photos; quadratic in the number of images).
    Exhaustive,
}

impl Matcher {
    /// Both matchers.
    pub const ALL: [Matcher; 2] = [Matcher::Sequential, Matcher::Exhaustive];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// One line of help.
    pub fn help(self) -> &'static str {
        match self {
            Self::Sequential => "each frame against the next 10 (videos, ordered sequences)",
            Self::Exhaustive => "every pair of images (unordered photos; slow for many)",
        }
    }

    /// The COLMAP command.
    pub fn colmap_command(self) -> &'static str {
        match self {
            Self::Sequential => "sequential_matcher",
            Self::Exhaustive => "exhaustive_matcher",
        }
    }
}

/// [`Matcher`]'s `from_str` error: "unknown matcher `x`; expected sequential or exhaustive".
impl OneWord for Matcher {
    const FIELD: &'static str = "matcher";
}

/// What `prepare` is asked to do.
#[derive(Clone, Debug, PartialEq)]
pub struct PrepareRequest {
    /// The video or the image folder.
    pub source: Source,
    /// The dataset folder to create (must not exist, or be empty).
    pub out: PathBuf,
    /// Frames per second to take from a video (`None`: every frame), lowered when the clip
    /// would give more than `max_frames`.
    pub fps: Option<f64>,
    /// At most this many frames (spread over the whole clip; the first ones of an image folder).
    pub max_frames: usize,
    /// Image size divisor, >= 1.
    pub downscale: f64,
    /// Pair selection for matching.
    pub matcher: Matcher,
    /// The reconstruction must register at least this fraction of the frames (and 3).
    pub min_registered: f64,
}

impl PrepareRequest {
    /// A request with the default settings: every frame up to 150, full size, sequential
    /// matching, at least 80% registered.
    pub fn new(source: Source, out: impl Into<PathBuf>) -> Self {
        Self {
            source,
            out: out.into(),
            fps: None,
            max_frames: 150,
            downscale: 1.0,
            matcher: Matcher::Sequential,
            min_registered: 0.8,
        }
    }

    fn validate(&self) -> Result<(), PrepareError> {
        let bad = |problem: String| Err(PrepareError::input(self.source.path(), problem));
        if let Some(f) = self.fps
            && !(f.is_finite() && f > 0.0)
        {
            return bad(format!("--fps {f}: must be a positive number"));
        }
        if self.max_frames < frames::MIN_FRAMES {
            return bad(format!(
                "--max-frames {}: must be at least {}",
                self.max_frames,
                frames::MIN_FRAMES
            ));
        }
        if !(self.downscale.is_finite() && self.downscale >= 1.0) {
            return bad(format!(
                "--downscale {}: must be a number >= 1 (2 halves the size)",
                self.downscale
            ));
        }
        if !(0.0..=1.0).contains(&self.min_registered) {
            return bad(format!(
                "--min-registered {}: must be a fraction in [0, 1]",
                self.min_registered
            ));
        }
        match &self.source {
            Source::Video(p) if p.is_dir() => bad("--video: is a folder (use --images)".into()),
            Source::Video(p) if !p.is_file() => bad("--video: no such video file".into()),
            Source::Images(p) if p.exists() && !p.is_dir() => {
                bad("--images: is a file, not a folder of images (use --video)".into())
            }
            Source::Images(p) if !p.is_dir() => bad("--images: no such folder".into()),
            _ => Ok(()),
        }
    }
}

/// A stage of the pipeline ([`Display`](std::fmt::Display): its lower-case name).
#[derive(strum::Display, strum::IntoStaticStr)]
#[strum(serialize_all = "lowercase")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// Frame extraction (ffmpeg) or copying.
    Frames,
    /// SIFT features.
    Features,
    /// Feature matching.
    Matching,
    /// Incremental mapping.
    Mapping,
    /// Undistortion (only when the camera has distortion).
    Undistortion,
    /// Writing and checking the dataset.
    Dataset,
}

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 6] = [
        Stage::Frames,
        Stage::Features,
        Stage::Matching,
        Stage::Mapping,
        Stage::Undistortion,
        Stage::Dataset,
    ];

    /// The stage's name (its log is `logs/<name>.log`).
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// 1-based position.
    pub fn number(self) -> usize {
        Self::ALL.iter().position(|&s| s == self).unwrap_or(0) + 1
    }

    /// What it does, for progress lines.
    pub fn doing(self) -> &'static str {
        match self {
            Self::Frames => "extracting frames (ffmpeg)",
            Self::Features => "SIFT features on the CPU (colmap feature_extractor)",
            Self::Matching => "matching features (colmap)",
            Self::Mapping => "structure from motion (colmap mapper)",
            Self::Undistortion => "undistorting to pinhole images (colmap image_undistorter)",
            Self::Dataset => "writing the dataset",
        }
    }
}

/// Progress reported while preparing.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A stage starts.
    Started(Stage),
    /// A stage ended after `seconds`; `note` says what it produced.
    Finished {
        /// The stage.
        stage: Stage,
        /// Wall-clock seconds.
        seconds: f64,
        /// What it produced, e.g. `36 frames`.
        note: String,
    },
    /// A stage was not needed.
    Skipped {
        /// The stage.
        stage: Stage,
        /// Why.
        reason: String,
    },
}

/// One stage's time, as recorded in `prepare.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageTime {
    /// The stage.
    pub stage: Stage,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// What `prepare` made, written to `DIR/prepare.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PrepareSummary {
    /// The video or image folder.
    pub source: PathBuf,
    /// Frames extracted (or images copied).
    pub frames: usize,
    /// Frames COLMAP registered (the dataset's images).
    pub registered: usize,
    /// Frames not registered, by name (left out of the dataset).
    pub unregistered: Vec<String>,
    /// Frames per second taken from a video (`None`: every frame, or an image folder).
    pub fps: Option<f64>,
    /// Sparse points of the reconstruction (the initial Gaussians).
    pub points: usize,
    /// The fitted camera before undistortion: COLMAP model name and parameters.
    pub camera: (String, Vec<f64>),
    /// Whether the images were undistorted.
    pub undistorted: bool,
    /// Image size of the dataset.
    pub image_size: (u32, u32),
    /// Size of the extracted frames (the fitted camera's, before undistortion).
    pub frame_size: (u32, u32),
    /// Pair selection used.
    pub matcher: Matcher,
    /// The programs' versions.
    pub tools: Vec<String>,
    /// Seconds per stage.
    pub stage_seconds: Vec<StageTime>,
}

/// Below this share of the frames registered, the dataset gets a warning (its views and times are
/// what COLMAP kept: a clip mostly dropped trains on a handful of views).
pub const WARN_REGISTERED_SHARE: f64 = 0.5;

/// Below this share of the frames' pixels left after undistortion, the dataset gets a warning
/// (issue 49: a 400×400 clip cropped to 80×80, 4 % of its pixels, "succeeded" silently).
pub const WARN_PIXEL_SHARE: f64 = 0.5;

impl PrepareSummary {
    /// What a user should know before training on the dataset: most frames dropped
    /// ([`WARN_REGISTERED_SHARE`]), frames cropped by undistortion ([`WARN_PIXEL_SHARE`]). One
    /// line each; none when the dataset is whole.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if (self.registered as f64) < WARN_REGISTERED_SHARE * self.frames as f64 {
            out.push(format!(
                "only {} of {} frames registered: the dataset holds those views and times only; \
                 try --matcher exhaustive, a higher --fps or a clip with more texture and \
                 sideways motion",
                self.registered, self.frames
            ));
        }
        let pixels = |(w, h): (u32, u32)| w as f64 * h as f64;
        let share = pixels(self.image_size) / pixels(self.frame_size).max(1.0);
        if self.undistorted && share < WARN_PIXEL_SHARE {
            out.push(format!(
                "undistortion cropped the frames from {}x{} to {}x{} ({:.0} % of the pixels): \
                 COLMAP's fitted distortion ({}) is likely wrong for this clip; more frames or \
                 --matcher exhaustive may fit a better one",
                self.frame_size.0,
                self.frame_size.1,
                self.image_size.0,
                self.image_size.1,
                100.0 * share,
                self.camera.0
            ));
        }
        out
    }
}

/// The dataset's sparse model folder inside `DIR`.
pub const SPARSE_DIR: &str = "sparse/0";
/// The dataset's image folder inside `DIR`.
pub const IMAGES_DIR: &str = "images";
/// The stage logs inside `DIR`.
pub const LOGS_DIR: &str = "logs";
/// The summary file inside `DIR`.
pub const SUMMARY_FILE: &str = "prepare.json";

fn rename(from: &Path, to: &Path) -> Result<(), PrepareError> {
    std::fs::rename(from, to).map_err(|e| PrepareError::io(to, e))
}

/// The output folder must not exist, or be an empty folder (then removed and replaced).
fn check_out(out: &Path) -> Result<(), PrepareError> {
    if !out.exists() {
        return Ok(());
    }
    let empty = out.is_dir()
        && std::fs::read_dir(out)
            .map_err(|e| PrepareError::io(out, e))?
            .next()
            .is_none();
    if empty {
        Ok(())
    } else {
        Err(PrepareError::input(
            out,
            "already exists; choose a new --out (nothing is overwritten)",
        ))
    }
}

/// Runs the pipeline (see the crate docs); `progress` hears each stage start and end.
pub fn prepare(
    request: &PrepareRequest,
    progress: &mut dyn FnMut(&Event),
) -> Result<PrepareSummary, PrepareError> {
    request.validate()?;
    check_out(&request.out)?;
    let mut tools = Vec::new();
    let needs_ffmpeg = matches!(request.source, Source::Video(_)) || request.downscale != 1.0;
    if needs_ffmpeg {
        tools.push(tools::FFMPEG.version()?);
        if matches!(request.source, Source::Video(_)) {
            tools::FFPROBE.version()?;
        }
    }
    tools.push(tools::COLMAP.version()?);

    let out = std::path::absolute(&request.out).map_err(|e| PrepareError::io(&request.out, e))?;
    let parent = out.parent().unwrap_or(Path::new("/")).to_path_buf();
    std::fs::create_dir_all(&parent).map_err(|e| PrepareError::io(&parent, e))?;
    let name = out
        .file_name()
        .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
    // Removed on every early return: nothing half-written is left.
    let temp = tempfile::Builder::new()
        .prefix(&format!(".{name}.prepare-"))
        .tempdir_in(&parent)
        .map_err(|e| PrepareError::io(&parent, e))?;
    let root = temp.path();
    let logs = root.join(LOGS_DIR);
    let work = root.join("work");
    for dir in [&logs, &work] {
        std::fs::create_dir_all(dir).map_err(|e| PrepareError::io(dir, e))?;
    }
    let log = |stage: Stage| logs.join(format!("{}.log", stage.name()));
    let subject = request.source.path().to_path_buf();
    // Every stage inside one closure: a failure after a stage ran keeps the stages' logs
    // ([`failed_logs_dir`]) before the temporary folder goes.
    let stages = || -> Result<PrepareSummary, PrepareError> {
        let mut times = Vec::new();
        let mut timed =
            |stage: Stage, progress: &mut dyn FnMut(&Event), started: Instant, note: String| {
                let seconds = started.elapsed().as_secs_f64();
                times.push(StageTime { stage, seconds });
                progress(&Event::Finished {
                    stage,
                    seconds,
                    note,
                });
            };
        // 1. Frames.
        progress(&Event::Started(Stage::Frames));
        let started = Instant::now();
        let frames_dir = work.join("frames");
        let (frames, fps) = frames::extract(request, &frames_dir, &log(Stage::Frames))?;
        timed(
            Stage::Frames,
            progress,
            started,
            format!("{} frames", frames.len()),
        );

        // 2–4. COLMAP.
        let database = work.join("database.db");
        progress(&Event::Started(Stage::Features));
        let started = Instant::now();
        sfm::features(&database, &frames_dir, &log(Stage::Features), &subject)?;
        timed(Stage::Features, progress, started, String::new());
        progress(&Event::Started(Stage::Matching));
        let started = Instant::now();
        sfm::matching(&database, request.matcher, &log(Stage::Matching), &subject)?;
        timed(
            Stage::Matching,
            progress,
            started,
            request.matcher.name().to_string(),
        );
        progress(&Event::Started(Stage::Mapping));
        let started = Instant::now();
        let sparse = work.join("sparse");
        let best = sfm::map(
            &database,
            &frames_dir,
            &sparse,
            &log(Stage::Mapping),
            &subject,
        )?;
        let registered = best.as_ref().map_or(0, |(m, _)| m.images.len());
        let needed = ((request.min_registered * frames.len() as f64).ceil() as usize)
            .max(frames::MIN_FRAMES);
        if registered < needed {
            return Err(PrepareError::input(
                &subject,
                format!(
                    "COLMAP registered {registered} of {} frames; at least {needed} are needed \
                     (--min-registered {}); frames need still texture, overlap and some sideways \
                     camera motion (mapper: {})",
                    frames.len(),
                    request.min_registered,
                    tools::last_message(&log(Stage::Mapping))
                ),
            ));
        }
        let Some((model, model_dir)) = best else {
            unreachable!("registered >= 3 implies a model");
        };
        let registered_names: std::collections::BTreeSet<&str> =
            model.images.iter().map(|i| i.name.as_str()).collect();
        let unregistered: Vec<String> = frames
            .iter()
            .filter_map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()))
            .filter(|n| !registered_names.contains(n.as_str()))
            .collect();
        timed(
            Stage::Mapping,
            progress,
            started,
            format!(
                "{registered} of {} frames registered, {} points",
                frames.len(),
                model.points.len()
            ),
        );
        let camera = model
            .cameras
            .first()
            .map(|c| (c.model.name().to_string(), c.params.clone()))
            .unwrap_or_default();
        let frame_size = model
            .cameras
            .first()
            .map_or((0, 0), |c| (c.width, c.height));

        // 5. Undistortion, when the camera has distortion.
        let images = root.join(IMAGES_DIR);
        let sparse_out = root.join(SPARSE_DIR);
        std::fs::create_dir_all(root.join("sparse")).map_err(|e| PrepareError::io(root, e))?;
        let undistorted = sfm::has_distortion(&model);
        if undistorted {
            progress(&Event::Started(Stage::Undistortion));
            let started = Instant::now();
            let undistorted_dir = work.join("undistorted");
            sfm::undistort(
                &frames_dir,
                &model_dir,
                &undistorted_dir,
                &log(Stage::Undistortion),
                &subject,
            )?;
            rename(&undistorted_dir.join("images"), &images)?;
            rename(&undistorted_dir.join("sparse"), &sparse_out)?;
            timed(Stage::Undistortion, progress, started, String::new());
        } else {
            progress(&Event::Skipped {
                stage: Stage::Undistortion,
                reason: "the camera has no distortion".into(),
            });
            std::fs::create_dir_all(&images).map_err(|e| PrepareError::io(&images, e))?;
            for name in &registered_names {
                rename(&frames_dir.join(name), &images.join(name))?;
            }
            rename(&model_dir, &sparse_out)?;
        }

        // 6. The dataset: each frame's time in the clip (the extracted frames are evenly spaced
        // in it, in order), the work folder goes, the result is read back as `evogs train` will.
        progress(&Event::Started(Stage::Dataset));
        let started = Instant::now();
        let span = frames.len().saturating_sub(1).max(1) as f64;
        let frame_times = evogs_io::FrameTimes {
            source: subject.display().to_string(),
            frames: frames
                .iter()
                .enumerate()
                .filter_map(|(i, f)| {
                    let name = f.file_name()?.to_string_lossy().into_owned();
                    Some((name, i as f64 / span))
                })
                .collect(),
        };
        evogs_io::write_frame_times(&root.join(evogs_io::TIMES_FILE), &frame_times)?;
        std::fs::remove_dir_all(&work).map_err(|e| PrepareError::io(&work, e))?;
        let dataset = evogs_io::load_dataset(root, &evogs_io::LoadOptions::default())?;
        let size = dataset
            .all_frames()
            .next()
            .map_or((0, 0), |f| (f.camera.camera.width, f.camera.camera.height));
        let points = dataset.points.as_ref().map_or(0, |p| p.positions.len());
        timed(Stage::Dataset, progress, started, dataset.summary());
        let summary = PrepareSummary {
            source: subject.clone(),
            frames: frames.len(),
            registered,
            unregistered,
            fps,
            points,
            camera,
            undistorted,
            image_size: size,
            frame_size,
            matcher: request.matcher,
            tools,
            stage_seconds: times,
        };
        let text = serde_json::to_string_pretty(&summary).map_err(|e| {
            PrepareError::io(
                root.join(SUMMARY_FILE),
                std::io::Error::other(e.to_string()),
            )
        })?;
        let summary_path = root.join(SUMMARY_FILE);
        std::fs::write(&summary_path, text).map_err(|e| PrepareError::io(&summary_path, e))?;
        // The temporary folder is private (0700); the dataset gets the usual 0755.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(root, std::fs::Permissions::from_mode(0o755))
                .map_err(|e| PrepareError::io(root, e))?;
        }
        if out.exists() {
            // check_out allowed only an empty folder.
            std::fs::remove_dir(&out).map_err(|e| PrepareError::io(&out, e))?;
        }
        std::fs::rename(root, &out).map_err(|e| PrepareError::io(&out, e))?;
        Ok(summary)
    };
    match stages() {
        Ok(summary) => {
            // Renamed: the TempDir guard must not delete anything now.
            let _ = temp.keep();
            Ok(summary)
        }
        Err(error) => Err(keep_logs(error, &logs, &out)),
    }
}

/// Where a failed run keeps its stages' logs: `OUT.logs` beside the output folder that was not
/// made (replaced by the next failure of the same `--out`).
pub fn failed_logs_dir(out: &Path) -> PathBuf {
    let name = out
        .file_name()
        .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
    out.with_file_name(format!("{name}.logs"))
}

/// `error`, with the stages' logs moved to [`failed_logs_dir`] and named in it when a stage wrote
/// any (a bad input found before any program ran leaves nothing).
fn keep_logs(error: PrepareError, logs: &Path, out: &Path) -> PrepareError {
    let wrote = std::fs::read_dir(logs).is_ok_and(|entries| {
        entries
            .flatten()
            .any(|e| e.metadata().is_ok_and(|m| m.len() > 0))
    });
    if !wrote {
        return error;
    }
    let kept = failed_logs_dir(out);
    let _ = std::fs::remove_dir_all(&kept);
    if std::fs::rename(logs, &kept).is_err() {
        return error;
    }
    PrepareError::WithLogs {
        error: Box::new(error),
        logs: kept,
    }
}

#[cfg(test)]
mod tests {
    use super::{Matcher, PrepareSummary, Stage};

    fn summary(
        frames: usize,
        registered: usize,
        frame: (u32, u32),
        image: (u32, u32),
    ) -> PrepareSummary {
        PrepareSummary {
            source: "clip.mp4".into(),
            frames,
            registered,
            unregistered: Vec::new(),
            fps: None,
            points: 100,
            camera: ("OPENCV".into(), Vec::new()),
            undistorted: image != frame,
            image_size: image,
            frame_size: frame,
            matcher: Matcher::Sequential,
            tools: Vec::new(),
            stage_seconds: Vec::new(),
        }
    }

    /// The case (10 of 50 frames, 400×400 cropped to 80×80) gets both warnings; a whole
    /// dataset none; each alone its own.
    #[test]
    fn dropped_and_cropped_frames_are_warned_about() {
        let bad = summary(50, 10, (400, 400), (80, 80)).warnings();
        assert_eq!(bad.len(), 2, "{bad:?}");
        assert!(
            bad[0].starts_with("only 10 of 50 frames registered"),
            "{bad:?}"
        );
        assert!(
            bad[1].contains("from 400x400 to 80x80 (4 % of the pixels)"),
            "{bad:?}"
        );
        assert!(
            summary(50, 48, (400, 400), (400, 400))
                .warnings()
                .is_empty()
        );
        assert!(
            summary(50, 48, (400, 400), (380, 376))
                .warnings()
                .is_empty()
        );
        assert_eq!(summary(50, 20, (400, 400), (400, 400)).warnings().len(), 1);
        assert_eq!(summary(50, 40, (400, 400), (200, 200)).warnings().len(), 1);
    }

    #[test]
    fn spellings_round_trip_and_unknown_ones_list_every_matcher() {
        for matcher in Matcher::ALL {
            assert_eq!(matcher.to_string().parse::<Matcher>(), Ok(matcher));
            assert_eq!(matcher.name(), matcher.to_string());
        }
        assert_eq!(
            "seq".parse::<Matcher>().unwrap_err(),
            "unknown matcher `seq`; expected sequential or exhaustive"
        );
        let names: Vec<String> = Stage::ALL.iter().map(ToString::to_string).collect();
        assert_eq!(
            names,
            [
                "frames",
                "features",
                "matching",
                "mapping",
                "undistortion",
                "dataset"
            ]
        );
    }
}
