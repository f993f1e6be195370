//! `evogs export`: a run's deformed Gaussians at a time (one file) or a sequence of times (a
//! folder with `sequence.json`), as 3DGS PLY, compressed PLY or `.splat`.

use anyhow::Result;
use evogs_eval::LoadedRun;
use evogs_eval::render::{ExportFormat, export_frame_as, export_sequence};

use std::path::PathBuf;

use clap::Args;

/// Arguments of `evogs export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Run directory written by `evogs train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,

    /// Time of one frame: training times lie in [0, 1]; any finite time is accepted (between
    /// frames, or beyond them: Φ's B-spline clamps to [0, 1], EvoGS's prior extrapolates the
    /// last frames).
    #[arg(
        long,
        value_name = "T",
        allow_negative_numbers = true,
        required_unless_present = "frames",
        conflicts_with = "frames"
    )]
    pub time: Option<f32>,

    /// A sequence of N frames at times evenly spaced over [0, 1] into the folder --out
    /// (frame_0000.ply or .compressed.ply or .splat, ... and sequence.json: format, count, files, times, Gaussians, the
    /// canonical bounds).
    #[arg(long, allow_negative_numbers = true, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: Option<u32>,

    /// File format: ply (INRIA 3DGS, every SH band, f32), compressed-ply (PlayCanvas/SuperSplat's
    /// .compressed.ply: about 16 bytes a Gaussian plus 1 per higher SH coefficient, quantised in
    /// chunks of 256 in Morton order) or splat (32 bytes a Gaussian: DC colour only, 8-bit colour,
    /// opacity and rotation; sorted by volume x opacity, largest first) [default: the one --out's
    /// extension names (.ply, .compressed.ply, .splat), else ply; a contradiction is refused].
    #[arg(long, value_parser = evogs_backbones::cli::words::<evogs_eval::render::ExportFormat>())]
    pub format: Option<evogs_eval::render::ExportFormat>,

    /// Output file (with --time) or folder (with --frames), each file written atomically.
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
}

/// Runs `evogs export`; returns the number of files and of Gaussians in the first.
pub fn run_export(args: &ExportArgs) -> Result<(usize, usize)> {
    let format = format_of(args)?;
    let mut run = LoadedRun::open(&args.run)?;
    match (args.frames, args.time) {
        (Some(n), _) => {
            let seq = export_sequence(&mut run, n as usize, format, &args.out)?;
            Ok((seq.count, seq.gaussians[0]))
        }
        (None, time) => {
            let n = export_frame_as(&mut run, time.unwrap_or(0.0), format, &args.out)?;
            Ok((1, n))
        }
    }
}

/// The format to write: `--format`, else the one the file name of `--out` says (one file; a
/// sequence's `--out` is a folder), else ply. A `--format` the file name contradicts is refused
/// (a PLY written into `x.splat` reads back as nothing).
fn format_of(args: &ExportArgs) -> Result<ExportFormat> {
    let named = args
        .frames
        .is_none()
        .then(|| ExportFormat::of_path(&args.out))
        .flatten();
    match (args.format, named) {
        (Some(given), Some(named)) if given != named => anyhow::bail!(
            "{}: --format {given} contradicts the file name, which says {named}",
            args.out.display()
        ),
        (Some(format), _) | (None, Some(format)) => Ok(format),
        (None, None) => Ok(ExportFormat::Ply),
    }
}
