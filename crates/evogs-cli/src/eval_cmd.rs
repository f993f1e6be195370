//! `evogs eval`: scores a run on a split and writes `eval_<split>.json` and `.md`; says in one
//! line on stderr when LPIPS weights are missing (and how to install them), and goes on.

use anyhow::Result;
use evogs_eval::LoadedRun;
use evogs_eval::eval::{EvalLpips, EvalReport, evaluate};
use evogs_metrics::lpips::Backbone;

use crate::args::EvalArgs;

/// Runs `evogs eval`.
pub fn run_eval(args: &EvalArgs) -> Result<EvalReport> {
    let split = args.split;
    let mut run = LoadedRun::open(&args.run)?;
    if let Some(t) = args.time_from {
        run.run.train.time_from = t.0;
    }
    println!("{}", run.use_backend(args.backend)?);
    let backbones: &[Backbone] = if args.lpips_vgg {
        &Backbone::ALL
    } else {
        &[Backbone::Alex]
    };
    let lpips = EvalLpips::find(backbones, args.lpips_weights.as_deref())?;
    for line in &lpips.missing {
        eprintln!("evogs eval: {line}; reporting the other metrics");
    }
    Ok(evaluate(&mut run, split, &lpips)?)
}
