//! `evogs eval`: scores a run on a split and writes `eval_<split>.json` and `.md`.

use anyhow::{Result, anyhow};
use evogs_io::Split;
use evogs_train::LoadedRun;
use evogs_train::eval::{EvalReport, evaluate};

use crate::args::EvalArgs;

/// Runs `evogs eval`.
pub fn run_eval(args: &EvalArgs) -> Result<EvalReport> {
    let split: Split = args
        .split
        .parse()
        .map_err(|e: String| anyhow!("--split: {e}"))?;
    let mut run = LoadedRun::open(&args.run)?;
    println!("{}", run.use_backend(args.backend)?);
    Ok(evaluate(&mut run, split)?)
}
