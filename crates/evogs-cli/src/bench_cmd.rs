//! `evogs bench`: the D-NeRF benchmark (scenes × methods, one table with the published figures,
//! a PSNR-against-time plot, a picture per scene). Thin: the runner and the outputs are
//! `evogs_experiments::bench`; this module reads the flags and prints one line per run started,
//! curve point and run finished. With `--jobs N` it trains up to N runs at once, each in a
//! process of its own (this executable again, with the hidden `--part`), and gathers their rows
//! into the one table.

use std::path::PathBuf;
use std::process::{Child, Command};

use anyhow::{Context, Result};
use clap::Args;
use evogs_eval::eval::EvalLpips;
use evogs_experiments::bench::{
    BenchProgress, BenchRequest, BenchRun, BenchScene, read_run_record, run_bench, run_bench_runs,
    write_summaries,
};
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

    /// Training preset of every run (the bench's own default: the D-NeRF benchmark's).
    #[arg(long, default_value_t = Preset::Dnerf, value_parser = evogs_backbones::cli::words::<Preset>())]
    pub preset: Preset,

    /// Iterations per run (scales the preset's schedule) [default: the preset's].
    #[arg(long, allow_negative_numbers = true, value_name = "N", value_parser = crate::shared_args::whole::<u64>(1))]
    pub iterations: Option<u64>,

    /// Every run's time budget.
    #[command(flatten)]
    pub budget: crate::shared_args::BudgetArgs,

    /// Curve points (PSNR on the headline split) every this many iterations.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1000, value_name = "N", value_parser = crate::shared_args::whole::<u64>(1))]
    pub eval_every: u64,

    /// The deformation backbone of every run (EvoGS runs use Φ built from it) and SC-GS's
    /// settings.
    #[command(flatten)]
    pub backbone: crate::shared_args::BackboneArgs,

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

    /// Train up to N runs at once, each in a process of its own with RAYON_NUM_THREADS = the
    /// threads / N (at least 1), so each run's peak memory and CPU-time budget are its own: on
    /// 2 cores `--jobs 2` trains the two methods side by side, one thread each. The table, plot
    /// and pictures gather every run once all have finished.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_name = "N", value_parser = crate::shared_args::whole::<u64>(1))]
    pub jobs: u64,

    /// (Internal, for --jobs) train and evaluate the runs and write each run's record, but not
    /// the table, plot or pictures.
    #[arg(long, hide = true)]
    pub part: bool,
}

/// The flags of `args` that every run shares, as `evogs bench` reads them back (a `--jobs`
/// part gets these with its own `--data`, `--methods` and `--out`).
fn shared_flags(args: &BenchArgs) -> Vec<String> {
    let mut f = vec![
        "--preset".to_string(),
        args.preset.to_string(),
        "--eval-every".to_string(),
        args.eval_every.to_string(),
    ];
    f.extend(args.backbone.flags(args.preset));
    if let Some(n) = args.iterations {
        f.extend(["--iterations".to_string(), n.to_string()]);
    }
    if let Some(seconds) = args.budget.time_budget {
        f.extend(["--time-budget".to_string(), format!("{seconds}s")]);
    }
    if let Some(clock) = args.budget.budget_clock {
        f.extend(["--budget-clock".to_string(), clock.to_string()]);
    }
    if let Some(s) = args.seed {
        f.extend(["--seed".to_string(), s.to_string()]);
    }
    if args.lpips_vgg {
        f.push("--lpips-vgg".to_string());
    }
    if let Some(dir) = &args.lpips_weights {
        f.extend(["--lpips-weights".to_string(), dir.display().to_string()]);
    }
    f
}

/// Trains every scene × method of `request` in up to `args.jobs` processes at once (this
/// executable with `--part`, one run each), then reads their records in the request's order.
fn run_in_parts(args: &BenchArgs, request: &BenchRequest) -> Result<Vec<BenchRun>> {
    let exe = std::env::current_exe().context("evogs bench --jobs: finding this executable")?;
    let jobs = args.jobs as usize;
    let threads = (rayon::current_num_threads() / jobs).max(1);
    let shared = shared_flags(args);
    let mut pending: Vec<(&BenchScene, Method)> = request
        .scenes
        .iter()
        .flat_map(|scene| request.methods.iter().map(move |&m| (scene, m)))
        .collect();
    pending.reverse();
    let mut running: Vec<(Child, String)> = Vec::new();
    let mut failures = Vec::new();
    while !pending.is_empty() || !running.is_empty() {
        while running.len() < jobs && failures.is_empty() {
            let Some((scene, method)) = pending.pop() else {
                break;
            };
            let child = Command::new(&exe)
                .arg("bench")
                .arg("--part")
                .arg("--data")
                .arg(&scene.data)
                .args(["--methods", &method.to_string()])
                .arg("--out")
                .arg(&request.out)
                .args(&shared)
                .env("RAYON_NUM_THREADS", threads.to_string())
                .spawn()
                .with_context(|| format!("evogs bench --jobs: starting {}", exe.display()))?;
            running.push((child, format!("{} {method}", scene.name)));
        }
        if !failures.is_empty() {
            // Start no more runs; wait for those running.
            pending.clear();
        }
        let mut still = Vec::with_capacity(running.len());
        for (mut child, label) in running {
            match child.try_wait()? {
                Some(status) if !status.success() => {
                    failures.push(format!("{label} ({status})"));
                }
                Some(_) => {}
                None => still.push((child, label)),
            }
        }
        running = still;
        if !running.is_empty() {
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
    }
    anyhow::ensure!(
        failures.is_empty(),
        "evogs bench --jobs: failed runs: {} (their errors are above)",
        failures.join(", ")
    );
    let mut runs = Vec::new();
    for scene in &request.scenes {
        for method in &request.methods {
            let dir = request.out.join(&scene.name).join(method.to_string());
            runs.push(read_run_record(&dir)?);
        }
    }
    Ok(runs)
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
    args.backbone.apply(&mut config);
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
    let runs = request.scenes.len() * request.methods.len();
    if args.jobs > 1 && runs > 1 && !args.part {
        // The parts load LPIPS themselves (and say what is missing).
        request.config.validate()?;
        let runs = run_in_parts(args, &request)?;
        write_summaries(&request, &runs)?;
        return Ok(runs);
    }
    for line in &lpips.missing {
        eprintln!("LPIPS not reported: {line}");
    }
    let bench = if args.part { run_bench_runs } else { run_bench };
    // On a terminal a bar over the current run's schedule, the lines above it.
    let mut bar: Option<crate::progress::Steps> = None;
    let mut label = String::new();
    let say = |bar: &Option<crate::progress::Steps>, line: String| match bar {
        Some(b) => b.println(&line),
        None => eprintln!("{line}"),
    };
    let runs = bench(&request, &lpips, &mut |p| match p {
        BenchProgress::Started { scene, method } => {
            eprintln!("{scene} {method}: started");
            label = format!("{scene} {method}");
        }
        BenchProgress::Step {
            schedule_iteration,
            schedule,
        } => {
            if bar.is_none() {
                bar = crate::progress::Steps::new(schedule, label.clone()).ok();
            }
            if let Some(b) = &bar {
                b.set(schedule_iteration);
            }
        }
        BenchProgress::Point {
            scene,
            method,
            point,
        } => say(
            &bar,
            format!(
                "{scene} {method}: iteration {}, {:.1} min, PSNR {:.2} dB",
                point.iteration,
                point.seconds / 60.0,
                point.psnr
            ),
        ),
        BenchProgress::Finished { run } => {
            if let Some(b) = bar.take() {
                b.finish();
            }
            eprintln!(
                "{} {}: finished in {:.1} min, {} steps, {} PSNR {:.2} dB, {} Gaussians",
                run.scene,
                run.method,
                run.seconds / 60.0,
                run.iterations,
                run.headline,
                run.score(&run.headline).map_or(f64::NAN, |s| s.psnr),
                run.gaussians
            );
            if run.schedule_lagged > 0 {
                eprintln!(
                    "warning: {} {}: its schedule fell behind the time budget: the last step took \
                     {} schedule iterations at once (marked \"lagged\" in bench.md); for a \
                     schedule that fits, run it with --iterations near {}",
                    run.scene, run.method, run.schedule_lagged, run.iterations
                );
            }
        }
    });
    if let Some(b) = bar.take() {
        b.finish();
    }
    Ok(runs?)
}
