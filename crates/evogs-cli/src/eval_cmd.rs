//! `evogs eval`: scores a run on a split and writes `eval_<split>.json` and `.md`; says in one
//! line on stderr when LPIPS weights are missing (and how to install them), and goes on.

use anyhow::Result;
use evogs_eval::LoadedRun;
use evogs_eval::eval::{EvalLpips, EvalReport, evaluate_with_progress};
use evogs_metrics::lpips::Backbone;

use std::path::PathBuf;

use clap::Args;

use crate::shared_args::{RasterArgs, TimeFromArg};

/// Arguments of `evogs eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Run directory written by `evogs train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,

    /// Split to evaluate.
    #[arg(long, default_value = "test", value_name = "test|val|train")]
    pub split: evogs_io::Split,

    /// Times of frames whose dataset stores none, instead of the rule the run trained with.
    #[arg(long, value_name = "RULE")]
    pub time_from: Option<TimeFromArg>,

    /// The rasterizer backend.
    #[command(flatten)]
    pub raster: RasterArgs,

    /// Also report LPIPS with the VGG16 backbone (`lpips_vgg`); `lpips_alex` (AlexNet) is
    /// always reported when its weights are installed.
    #[arg(long)]
    pub lpips_vgg: bool,

    /// Directory of the LPIPS weights [default: $EVOGS_LPIPS_WEIGHTS, else
    /// ~/.cache/evogs/lpips; `scripts/lpips-weights` installs them there].
    #[arg(long, value_name = "DIR")]
    pub lpips_weights: Option<PathBuf>,
}

/// Runs `evogs eval`.
pub fn run_eval(args: &EvalArgs) -> Result<EvalReport> {
    let split = args.split;
    let mut run = LoadedRun::open(&args.run)?;
    if let Some(t) = args.time_from {
        run.run.train.time_from = t.0;
    }
    println!("{}", run.use_backend(args.raster.backend)?);
    let backbones: &[Backbone] = if args.lpips_vgg {
        &Backbone::ALL
    } else {
        &[Backbone::Alex]
    };
    let lpips = EvalLpips::find(backbones, args.lpips_weights.as_deref())?;
    for line in &lpips.missing {
        eprintln!("evogs eval: {line}; reporting the other metrics");
    }
    let mut progress: Option<crate::progress::Counted> = None;
    let report = evaluate_with_progress(&mut run, split, &lpips, &mut |done, total| {
        let counted = progress.get_or_insert_with(|| {
            crate::progress::Counted::new(total, "view").expect("a fixed progress template")
        });
        counted.inc();
        debug_assert!(done <= total);
    })?;
    if let Some(p) = progress {
        p.finish();
    }
    Ok(report)
}
