//! `evogs bench`: the D-NeRF benchmark (scenes × methods, one table with the published figures,
//! a PSNR-against-time plot, a picture per scene). Thin: the runner and the outputs are
//! `evogs_experiments::bench`; this module reads the flags and prints one line per run started,
//! curve point and run finished.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use evogs_eval::eval::EvalLpips;
use evogs_experiments::bench::{BenchProgress, BenchRequest, BenchRun, BenchScene, run_bench};
use evogs_metrics::lpips::Backbone;
use evogs_train::{Method, Preset, TrainConfig};

/// Arguments of `evogs bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Dataset directories, comma-separated (each a scene, named by its directory without a
    /// `dnerf-` prefix: `…/dnerf-lego` is `lego`).
    #[arg(long, value_name = "DIR,…", value_delimiter = ',', required = true)]
    pub data: Vec<PathBuf>,

    /// Output directory: `<scene>/<method>/` runs, bench.md, bench.json, bench.png, `<scene>.png`.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Methods, comma-separated, in table order.
    #[arg(
        long,
        value_name = "baseline,evogs",
        value_delimiter = ',',
        default_value = "baseline,evogs"
    )]
    pub methods: Vec<Method>,

    /// Training preset of every run.
    #[arg(long, default_value = "dnerf", value_name = "dnerf|cpu|tiny|paper")]
    pub preset: Preset,

    /// Iterations per run (scales the preset's schedule) [default: the preset's].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub iterations: Option<u64>,

    /// Every run's time budget.
    #[command(flatten)]
    pub budget: crate::args::BudgetArgs,

    /// Curve points (PSNR on the headline split) every this many iterations.
    #[arg(long, default_value_t = 1000, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub eval_every: u64,

    /// Deformation backbone of every run (EvoGS runs use Φ built from its field; d3dgs: the
    /// tri-plane Φ).
    #[arg(long, default_value = "d3dgs", value_name = "d3dgs|4dgs|grid4d")]
    pub backbone: evogs_train::BackboneKind,

    /// Seed of every run.
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,

    /// Also report LPIPS with the VGG16 backbone (the one D-3DGS publishes); AlexNet's is
    /// always reported when its weights are installed.
    #[arg(long)]
    pub lpips_vgg: bool,

    /// Directory of the LPIPS weights [default: $EVOGS_LPIPS_WEIGHTS, else
    /// ~/.cache/evogs/lpips; `scripts/lpips-weights` installs them there].
    #[arg(long, value_name = "DIR")]
    pub lpips_weights: Option<PathBuf>,
}

/// Runs `evogs bench`; returns the runs (the outputs are written).
pub fn run_bench_cmd(args: &BenchArgs) -> Result<Vec<BenchRun>> {
    let mut config = TrainConfig::preset(args.preset);
    if let Some(n) = args.iterations {
        config = config.with_iterations(n);
    }
    config.budget = args.budget.budget();
    if let Some(s) = args.seed {
        config.seed = s;
    }
    config.backbone = args.backbone;
    let methods = args.methods.clone();
    let request = BenchRequest {
        scenes: args.data.iter().map(|d| BenchScene::from_dir(d)).collect(),
        methods,
        config,
        eval_every: args.eval_every,
        out: args.out.clone(),
    };
    let backbones: &[Backbone] = if args.lpips_vgg {
        &Backbone::ALL
    } else {
        &[Backbone::Alex]
    };
    let lpips = EvalLpips::find(backbones, args.lpips_weights.as_deref())?;
    for line in &lpips.missing {
        eprintln!("LPIPS not reported: {line}");
    }
    Ok(run_bench(&request, &lpips, &mut |p| match p {
        BenchProgress::Started { scene, method } => eprintln!("{scene} {method}: started"),
        BenchProgress::Point {
            scene,
            method,
            point,
        } => eprintln!(
            "{scene} {method}: iteration {}, {:.1} min, PSNR {:.2} dB",
            point.iteration,
            point.seconds / 60.0,
            point.psnr
        ),
        BenchProgress::Finished { run } => eprintln!(
            "{} {}: finished in {:.1} min, {} PSNR {:.2} dB, {} Gaussians",
            run.scene,
            run.method,
            run.seconds / 60.0,
            run.headline,
            run.score(&run.headline).map_or(f64::NAN, |s| s.psnr),
            run.gaussians
        ),
    })?)
}
