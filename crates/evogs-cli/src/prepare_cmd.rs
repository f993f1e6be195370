//! `evogs prepare`: a video or an image folder in, a COLMAP dataset out (see `evogs-prepare`),
//! with one progress line per stage.

use std::path::PathBuf;

use anyhow::Result;
use clap::builder::PossibleValue;
use clap::{Args, ValueEnum};
use evogs_prepare::{Event, Matcher, PrepareRequest, PrepareSummary, Source, Stage, prepare};

/// A matcher as a command-line value; names and help come from the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MatcherArg(pub Matcher);

const MATCHER_ARGS: [MatcherArg; 2] = [
    MatcherArg(Matcher::Sequential),
    MatcherArg(Matcher::Exhaustive),
];

impl ValueEnum for MatcherArg {
    fn value_variants<'a>() -> &'a [Self] {
        &MATCHER_ARGS
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()).help(self.0.help()))
    }
}

/// Arguments of `evogs prepare`.
#[derive(Debug, Args)]
#[command(
    after_help = "Stages: frames (ffmpeg), features, matching and mapping (COLMAP on the CPU), \
                  undistortion (when the fitted camera has distortion), dataset. Writes \
                  DIR/images/, DIR/sparse/0/, DIR/logs/<stage>.log and DIR/prepare.json, built \
                  in a temporary folder beside DIR and renamed at the end: a failure leaves \
                  nothing. Needs the Debian packages ffmpeg and colmap. Then: evogs train \
                  --data DIR (times from the frame order)."
)]
pub struct PrepareArgs {
    /// A video file (anything ffmpeg decodes: mp4, mov, …).
    #[arg(
        long,
        value_name = "CLIP",
        conflicts_with = "images",
        required_unless_present = "images"
    )]
    pub video: Option<PathBuf>,

    /// A folder of .png/.jpg images, in name order, instead of a video.
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,

    /// The dataset folder to create (must not exist or be empty).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Frames per second to take from the video [default: every frame], lowered so that the
    /// whole clip fits in --max-frames.
    #[arg(long, value_name = "F")]
    pub fps: Option<f64>,

    /// At most this many frames (spread over the whole clip; the first of an image folder).
    #[arg(long, allow_negative_numbers = true, value_name = "N", default_value_t = 150,
          value_parser = clap::value_parser!(u32).range(3..=100_000))]
    pub max_frames: u32,

    /// Divide the image size by this (2 halves it) before COLMAP.
    #[arg(long, value_name = "F", default_value_t = 1.0)]
    pub downscale: f64,

    /// Which frame pairs COLMAP matches.
    #[arg(long, value_name = "KIND", default_value = "sequential")]
    pub matcher: MatcherArg,

    /// Stop with an error when COLMAP registers fewer than this fraction of the frames.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.8)]
    pub min_registered: f64,
}

/// Runs `evogs prepare`, printing a line as each stage starts and ends.
pub fn run_prepare(args: &PrepareArgs) -> Result<PrepareSummary> {
    let source = match (&args.video, &args.images) {
        (Some(video), _) => Source::Video(video.clone()),
        (None, Some(images)) => Source::Images(images.clone()),
        (None, None) => anyhow::bail!("give --video CLIP or --images DIR"),
    };
    let request = PrepareRequest {
        fps: args.fps,
        max_frames: args.max_frames as usize,
        downscale: args.downscale,
        matcher: args.matcher.0,
        min_registered: args.min_registered,
        ..PrepareRequest::new(source, &args.out)
    };
    let total = Stage::ALL.len();
    // On a terminal a spinner with the time spent shows that a long stage (COLMAP's mapper can
    // take minutes) is alive.
    let mut spinner: Option<crate::progress::Spinner> = None;
    let summary = prepare(&request, &mut |event| match event {
        Event::Started(stage) => {
            let line = format!(
                "[{}/{total}] {}: {} …",
                stage.number(),
                stage,
                stage.doing()
            );
            spinner = Some(crate::progress::Spinner::new(line));
        }
        Event::Finished {
            stage,
            seconds,
            note,
        } => {
            if let Some(s) = spinner.take() {
                s.finish();
            }
            let note = if note.is_empty() {
                String::new()
            } else {
                format!(": {note}")
            };
            eprintln!(
                "[{}/{total}] {stage} done in {seconds:.1} s{note}",
                stage.number()
            );
        }
        Event::Skipped { stage, reason } => {
            if let Some(s) = spinner.take() {
                s.finish();
            }
            eprintln!("[{}/{total}] {stage} skipped: {reason}", stage.number());
        }
    })?;
    if let Some(s) = spinner.take() {
        s.finish();
    }
    for warning in summary.warnings() {
        eprintln!("warning: {warning}");
    }
    Ok(summary)
}

/// The closing line.
pub fn report_line(args: &PrepareArgs, s: &PrepareSummary) -> String {
    format!(
        "wrote {}: {} of {} frames registered, {} points, {}x{} pinhole images{}; train with: \
         evogs train --data {}",
        args.out.display(),
        s.registered,
        s.frames,
        s.points,
        s.image_size.0,
        s.image_size.1,
        if s.undistorted { " (undistorted)" } else { "" },
        args.out.display()
    )
}
