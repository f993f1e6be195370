//! `evogs ablate`: the paper's ablation ladder at equal iterations on one dataset. Thin: the
//! ladder, the runner and the outputs are `evogs_experiments::ablate`; this module reads the flags and
//! shows progress (one line per row started and finished, and a bar on a terminal).

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use evogs_eval::eval::EvalLpips;
use evogs_experiments::ablate::{
    AblationRequest, AblationResult, Progress, run_ablation, seeds_from, select,
};
use evogs_metrics::lpips::Backbone;
use evogs_train::{Preset, TrainConfig};
use indicatif::{ProgressBar, ProgressStyle};

/// Arguments of `evogs ablate`.
#[derive(Debug, Args)]
pub struct AblateArgs {
    /// Dataset directory (any layout `evogs train` reads).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,

    /// Output directory: one run directory per row, ablation.md, ablation.json, ablation.png.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Training preset for every row.
    #[arg(long, default_value_t = Preset::default(), value_parser = evogs_backbones::cli::words::<Preset>())]
    pub preset: Preset,

    /// Iterations per row (scales the preset's schedule).
    #[arg(long, allow_negative_numbers = true, value_name = "N", value_parser = crate::shared_args::whole::<u64>(1))]
    pub iterations: Option<u64>,

    /// Every run's time budget.
    #[command(flatten)]
    pub budget: crate::shared_args::BudgetArgs,

    /// The deformation backbone of every row (the baseline rows train it, the EvoGS rows use
    /// Φ built from it) and SC-GS's settings.
    #[command(flatten)]
    pub backbone: crate::shared_args::BackboneArgs,

    /// Random seed for every row (the first seed with --seeds) [default: the preset's].
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,

    /// Runs every row with N training seeds (S, S+1, …; the scene stays the same) and reports
    /// mean ± sample standard deviation; run directories become `OUT/<row>/seed<S>`.
    #[arg(long, allow_negative_numbers = true, value_name = "N", default_value_t = 1,
          value_parser = crate::shared_args::whole::<u64>(1).to(100))]
    pub seeds: u64,

    /// Rows to run, comma-separated, in the ladder's order whatever the order given [default:
    /// all]: baseline, phi, evo-requery, evo-buffer, trigger, full, k0, k0.5, k1, net-f16,
    /// buffer-f16.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub rows: Vec<String>,

    /// Directory of the LPIPS weights for the `lpips_alex` columns [default:
    /// $EVOGS_LPIPS_WEIGHTS, else ~/.cache/evogs/lpips; `scripts/lpips-weights` installs them].
    #[arg(long, value_name = "DIR")]
    pub lpips_weights: Option<PathBuf>,
}

/// Runs `evogs ablate`; returns the results (the outputs are written).
pub fn run_ablate(args: &AblateArgs) -> Result<Vec<AblationResult>> {
    let mut config = TrainConfig::preset(args.preset);
    if let Some(n) = args.iterations {
        config = config.with_iterations(n);
    }
    config.budget = args.budget.budget();
    if let Some(s) = args.seed {
        config.seed = s;
    }
    args.backbone.apply(&mut config);
    let rows = select(&args.rows)?;
    let seeds = seeds_from(config.seed, args.seeds as usize);
    let request = AblationRequest {
        data: args.data.clone(),
        out: args.out.clone(),
        config,
        rows,
        seeds,
    };
    let multi = request.seeds.len() > 1;
    let seed_note = |seed: u64| {
        if multi {
            format!(" seed {seed}")
        } else {
            String::new()
        }
    };
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new((request.rows.len() * request.seeds.len()) as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} runs, ETA {eta} | {msg}")
            .context("progress bar template")?,
    );
    let lpips = EvalLpips::find(&[Backbone::Alex], args.lpips_weights.as_deref())?;
    for line in &lpips.missing {
        eprintln!("evogs ablate: {line}; the lpips_alex columns stay empty");
    }
    let results = run_ablation(&request, &lpips, &mut |p| match p {
        Progress::Started {
            index,
            total,
            row,
            seed,
        } => {
            bar.suspend(|| {
                eprintln!(
                    "row {}/{total} {}{}: started ({})",
                    index + 1,
                    row.name,
                    seed_note(seed),
                    row.switches()
                );
            });
            bar.set_message(row.name);
        }
        Progress::Finished {
            index,
            total,
            row,
            run,
        } => {
            bar.suspend(|| {
                eprintln!(
                    "row {}/{total} {}{}: finished in {:.1} s, test PSNR {:.2} dB",
                    index + 1,
                    row.name,
                    seed_note(run.seed),
                    run.scores.seconds,
                    run.scores.psnr
                );
            });
            bar.inc(1);
        }
    })?;
    bar.finish_and_clear();
    Ok(results)
}
