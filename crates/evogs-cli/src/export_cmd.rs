//! `evogs export`: a run's deformed Gaussians at a time (one file) or a sequence of times (a
//! folder with `sequence.json`), as 3DGS PLY, compressed PLY or `.splat`.

use anyhow::Result;
use evogs_eval::LoadedRun;
use evogs_eval::render::{export_frame_as, export_sequence};

use crate::args::ExportArgs;

/// Runs `evogs export`; returns the number of files and of Gaussians in the first.
pub fn run_export(args: &ExportArgs) -> Result<(usize, usize)> {
    let mut run = LoadedRun::open(&args.run)?;
    match (args.frames, args.time) {
        (Some(n), _) => {
            let seq = export_sequence(&mut run, n as usize, args.format, &args.out)?;
            Ok((seq.count, seq.gaussians[0]))
        }
        (None, time) => {
            let n = export_frame_as(&mut run, time.unwrap_or(0.0), args.format, &args.out)?;
            Ok((1, n))
        }
    }
}
