//! `evogs export`: a run's deformed Gaussians at a time as a 3DGS PLY.

use anyhow::Result;
use evogs_train::LoadedRun;
use evogs_train::render::export_frame;

use crate::args::ExportArgs;

/// Runs `evogs export`; returns the number of Gaussians written.
pub fn run_export(args: &ExportArgs) -> Result<usize> {
    let mut run = LoadedRun::open(&args.run)?;
    Ok(export_frame(&mut run, args.time, &args.out)?)
}
