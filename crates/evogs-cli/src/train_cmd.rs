//! `evogs train`: builds the settings from the preset and flags, trains with a progress bar
//! (or plain log lines when stderr is not a terminal) and prints the per-phase times.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use evogs_experiments::gain_table::gain_table;
use evogs_experiments::motion_report::MotionReport;
use evogs_train::run::checkpoint_follows;
use evogs_train::{TrainConfig, TrainRequest, TrainSummary, train};
use indicatif::{ProgressBar, ProgressStyle};

use clap::Args;
use splat_raster::BackendChoice;

use crate::shared_args::{BudgetArgs, TimeFromArg, by_preset, parse_backend};

/// Arguments of `evogs train`.
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Dataset directory: D-NeRF, nerfies, Neu3D, COLMAP (`evogs prepare` writes one) or
    /// nerfstudio; the layout is detected.
    #[arg(long, value_name = "DIR", required_unless_present = "resume")]
    pub data: Option<PathBuf>,

    /// Times of frames whose dataset stores none (COLMAP without times.json, nerfstudio without
    /// `time`); see the README's Datasets section for the names `name` accepts [default: order].
    #[arg(long, value_name = "RULE")]
    pub time_from: Option<TimeFromArg>,

    /// Run directory to write (config, checkpoint, PLY, weights, metrics).
    #[arg(long, value_name = "RUN")]
    pub out: PathBuf,

    /// Deformation method: baseline (D-3DGS) or evogs (EvoGS(D-3DGS): observation network Φ
    /// at half the width, evolution state, gain network Ψ).
    #[arg(long, default_value_t = evogs_train::Method::default(), value_parser = evogs_backbones::cli::words::<evogs_train::Method>())]
    pub method: evogs_train::Method,

    /// The deformation backbone and SC-GS's settings.
    #[command(flatten)]
    pub backbone: crate::shared_args::BackboneArgs,

    /// EvoGS's switches, each defaulting to `EvoSettings::default()`'s value.
    #[command(flatten)]
    pub evo: evogs_backbones::cli::EvoArgs,

    /// Schedule iterations over which the deformation network's learning rate decays from its
    /// start to its end value, as D-3DGS's `deform_lr_max_steps` [rates and preset values: see
    /// --help, read from the settings].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "N",
        value_parser = crate::shared_args::whole::<u64>(1),
        help = net_lr_decay_help()
    )]
    pub net_lr_decay: Option<u64>,

    /// Width of the deformation network (D-3DGS's MLP; EvoGS's Φ decodes at half of it)
    /// [preset values: see --help].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "W",
        value_parser = crate::shared_args::whole::<usize>(2),
        help = by_preset(
            "Width of the deformation network (D-3DGS's MLP; EvoGS's Φ decodes at half of it)",
            |c| c.net.width,
        )
    )]
    pub net_width: Option<usize>,

    /// Print, with each progress line, EvoGS's motion statistics since the last line: samples
    /// per decade of speed / extent with their mean θ (a diagnostic of the uncertainty trigger).
    #[arg(long)]
    pub motion_report: bool,

    /// Print, at the end, EvoGS's gain K over the last quarter of the iterations: mean, std and
    /// percentiles over all, moving and still Gaussians and per frame (also recorded as `gain`
    /// in train_metrics.json by every run).
    #[arg(long)]
    pub gain_report: bool,

    /// Settings preset: paper (D-3DGS's reference), cpu (2 cores), tiny (CI), dnerf (the
    /// D-NeRF benchmark, network lr decay not compressed), each with its iterations, network
    /// width and image scale [values: see --help].
    #[arg(
        long,
        default_value_t = evogs_train::Preset::default(),
        value_parser = evogs_backbones::cli::words::<evogs_train::Preset>(),
        help = by_preset(
            "Settings preset: paper (D-3DGS's reference), cpu (2 cores), tiny (CI), dnerf (the \
             D-NeRF benchmark, network lr decay not compressed); iterations, network width, \
             image scale",
            |c| format!("{} it, width {}, 1/{}", c.iterations, c.net.width, 1.0 / c.downscale),
        )
    )]
    pub preset: evogs_train::Preset,

    /// Iterations; the preset's schedule is scaled to this count (with --time-budget: the
    /// schedule's length, which the budget is mapped onto).
    #[arg(long, allow_negative_numbers = true, value_name = "N", value_parser = crate::shared_args::whole::<u64>(1))]
    pub iterations: Option<u64>,

    /// The time budget.
    #[command(flatten)]
    pub budget: BudgetArgs,

    /// Image resize factor, e.g. 2 trains lego at 400×400 [preset values: see --help].
    #[arg(
        long,
        value_name = "F",
        help = by_preset("Image resize factor, e.g. 2 trains lego at 400×400", |c| 1.0 / c.downscale)
    )]
    pub downscale: Option<f32>,

    /// Seed of everything random [the preset's: see --help].
    #[arg(long, value_name = "SEED", help = by_preset("Seed of everything random", |c| c.seed))]
    pub seed: Option<u64>,

    /// Continue the run in --out from its last checkpoint (its config.json decides the rest).
    #[arg(
        long,
        conflicts_with_all = ["data", "time_from", "method", "backbone", "preset", "iterations", "downscale", "seed", "background", "gain", "history", "densify", "buffer", "net_precision", "components", "motion_floor", "grid_lr_scale", "psi_lr", "bspline_controls", "bspline_width", "triplane_resolutions", "triplane_combine", "triplane_channels", "net_lr_decay", "net_width", "max_gaussians", "max_screen_radius", "memory_limit", "checkpoint_every", "time_budget", "budget_clock"]
    )]
    pub resume: bool,

    /// Replace the run already in --out: its files (config, checkpoint, PLY, weights,
    /// evolution state, log, metrics, evaluations, renders) are removed first. Without it,
    /// training into a directory that holds a run is refused.
    #[arg(long, conflicts_with = "resume")]
    pub force: bool,

    /// Background behind the Gaussians and the images' alpha [D-3DGS default for D-NeRF: black];
    /// random: a new uniform colour each training iteration behind both (so transparency cannot
    /// pass for the background's colour), black for evaluation and renders.
    #[arg(long, value_parser = evogs_backbones::cli::words::<evogs_train::Background>())]
    pub background: Option<evogs_train::Background>,

    /// Rasterizer backend: cpu, wgpu (the GPU through wgpu, any adapter; an error without
    /// one) or auto (wgpu on a hardware GPU, cpu otherwise). Recorded in the run; --resume keeps
    /// the run's unless given [default: `BackendChoice::default()`].
    #[arg(
        long,
        value_name = "cpu|wgpu|auto",
        value_parser = parse_backend,
        help = format!(
            "Rasterizer backend: cpu, wgpu (the GPU through wgpu, any adapter; an error without \
             one) or auto (wgpu on a hardware GPU, cpu otherwise). Recorded in the run; --resume \
             keeps the run's unless given [default: {}]",
            BackendChoice::default()
        )
    )]
    pub backend: Option<BackendChoice>,

    /// Where the deformation network runs: wgpu (on the rasterizer's device; needs --backend
    /// wgpu and a network with a GPU form, the d3dgs baseline's today), auto (there on a
    /// hardware GPU, the CPU otherwise) or cpu. Recorded in the run; --resume keeps the run's
    /// unless given [default: every preset's `net_backend`].
    #[arg(
        long,
        value_name = "cpu|wgpu|auto",
        value_parser = parse_backend,
        help = format!(
            "Where the deformation network runs: wgpu (on the rasterizer's device; needs \
             --backend wgpu and a network with a GPU form, the d3dgs baseline's today), auto \
             (there on a hardware GPU, the CPU otherwise) or cpu. Recorded in the run; --resume \
             keeps the run's unless given [default: {}]",
            TrainConfig::preset(evogs_train::Preset::Paper).net_backend
        )
    )]
    pub net_backend: Option<BackendChoice>,

    /// Densification never grows the Gaussians past this count (the largest gradients are
    /// densified first) [preset values: see --help].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "N",
        value_parser = crate::shared_args::whole::<usize>(1),
        help = max_gaussians_help()
    )]
    pub max_gaussians: Option<usize>,

    /// Prune Gaussians whose screen radius exceeded this many pixels since the last
    /// densification, after the first opacity reset (the 3DGS paper's 20) [default: no
    /// screen-size prune, as 3DGS's and D-3DGS's code; see docs/DESIGN.md].
    #[arg(long, value_name = "PX")]
    pub max_screen_radius: Option<f32>,

    /// Peak memory the run may use, e.g. 8G or 512M: the run refuses to start when its estimate
    /// (printed at the start) already exceeds it, and densification stops growing the Gaussians
    /// before the estimate would [default: no limit].
    #[arg(long, value_name = "BYTES", value_parser = parse_memory)]
    pub memory_limit: Option<u64>,

    /// Let glibc's allocator keep freed memory for reuse (its own default) instead of returning
    /// it after loading, densification and before each checkpoint: the peak resident memory was
    /// up to a quarter above the printed estimate on lego, at the same CPU time
    /// (results/memory.md). Not with a memory limit.
    #[arg(long, conflicts_with = "memory_limit")]
    pub keep_freed_memory: bool,

    /// Write the checkpoint (what --resume continues from) every N iterations [the preset's,
    /// scaled with --iterations].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "N",
        value_parser = crate::shared_args::whole::<u64>(1),
        help = by_preset(
            "Write the checkpoint (what --resume continues from) every N iterations, scaled \
             with --iterations",
            |c| c.checkpoint_every,
        )
    )]
    pub checkpoint_every: Option<u64>,

    /// Stop after this many iterations in total (the run stays resumable).
    #[arg(long, value_name = "N", hide = true)]
    pub stop_after: Option<u64>,
}

/// `--net-lr-decay`'s help, the network schedule's two ends read from the default settings.
fn net_lr_decay_help() -> String {
    let lr = TrainConfig::preset(evogs_train::Preset::default()).lr;
    let schedule = evogs_train::state::network_schedule(&lr);
    let (start, end) = (
        schedule.at(0),
        schedule.at(i64::try_from(lr.deform_max_steps).unwrap_or(i64::MAX)),
    );
    by_preset(
        &format!(
            "Schedule iterations over which the deformation network's learning rate (D-3DGS's \
             MLP, or EvoGS's Φ, its planes and controls at `--grid-lr-scale` times it) decays \
             from {start:.1e} to {end:.1e}, as D-3DGS's `deform_lr_max_steps`; counted on the \
             run's schedule (after `--iterations`), so the schedule's length decays it over the \
             whole run, under a time budget too (the dnerf preset decays it over more steps than \
             its schedule has, so it ends above {end:.1e})"
        ),
        |c| c.lr.deform_max_steps,
    )
}

/// `--max-gaussians`' help, its values read from the presets' caps and budgets.
fn max_gaussians_help() -> String {
    use evogs_train::{Method, Preset};
    let caps: Vec<String> = Preset::ALL
        .iter()
        .filter_map(|&p| {
            let c = TrainConfig::preset(p);
            let baseline = p.max_gaussians(Method::Baseline)?;
            let evogs = match (
                p.gaussian_view_budget(Method::Evogs),
                p.max_gaussians(Method::Evogs),
            ) {
                (Some(b), Some(m)) => format!(
                    "for evogs {b} / training views within {}..={m}",
                    c.init_points
                ),
                (_, m) => format!("for evogs {m:?}"),
            };
            Some(format!("{p} {baseline} for baseline, {evogs}"))
        })
        .collect();
    format!(
        "Densification never grows the Gaussians past this count (the largest gradients are \
         densified first) [preset: {}; the others no limit]",
        caps.join("; ")
    )
}

/// `--memory-limit`: a byte count with an optional K, M, G or T suffix.
fn parse_memory(text: &str) -> Result<u64, String> {
    evogs_train::memory::parse_bytes(text)
}

/// The settings the flags ask for.
pub fn config_from_args(args: &TrainArgs) -> Result<TrainConfig> {
    let mut config = TrainConfig::preset(args.preset);
    if let Some(n) = args.iterations {
        config = config.with_iterations(n);
    }
    config.budget = args.budget.budget();
    if let Some(f) = args.downscale {
        anyhow::ensure!(
            f.is_finite() && f >= 1.0,
            "--downscale {f}: must be a number >= 1 (2 halves the image size)"
        );
        config.downscale = 1.0 / f;
    }
    if let Some(b) = args.background {
        config.background = b;
    }
    config = config.with_method(args.method);
    args.backbone.apply(&mut config);
    args.evo.apply(&mut config.backbones.evogs);
    if let Some(v) = args.net_width {
        config.net.width = v;
    }
    if let Some(n) = args.net_lr_decay {
        config.lr.deform_max_steps = n;
    }
    if let Some(v) = args.max_gaussians {
        config.densify.max_gaussians = Some(v);
        config.gaussian_view_budget = None;
    }
    if let Some(v) = args.max_screen_radius {
        config.densify.max_screen_radius = Some(v);
    }
    config.memory_limit = args.memory_limit;
    if let Some(n) = args.checkpoint_every {
        config.checkpoint_every = n;
    }
    if let Some(t) = args.time_from {
        config.time_from = t.0;
    }
    if let Some(seed) = args.seed {
        config.seed = seed;
    }
    config.backend = args.backend.unwrap_or_default();
    if let Some(net_backend) = args.net_backend {
        config.net_backend = net_backend;
    }
    config.validate()?;
    Ok(config)
}

/// Refuses a directory that holds a run (naming `--resume` and `--force`), or with `force`
/// removes that run's files first (`RunPaths::clear_run`), so that two runs never mix.
fn make_room(out: &std::path::Path, force: bool) -> Result<()> {
    let paths = evogs_train::run::RunPaths::new(out);
    if !paths.holds_run() {
        return Ok(());
    }
    if !force {
        let held = [paths.config(), paths.checkpoint()]
            .into_iter()
            .find(|p| p.is_file())
            .unwrap_or_else(|| paths.config());
        anyhow::bail!(
            "{}: --out already holds a run ({}); continue it with --resume, or replace it with \
             --force",
            out.display(),
            held.file_name().unwrap_or_default().to_string_lossy()
        );
    }
    let removed = paths.clear_run()?;
    eprintln!(
        "evogs train: --force: removed the previous run in {} ({} files and folders)",
        out.display(),
        removed.len()
    );
    Ok(())
}

/// How `evogs train` keeps glibc's allocator from holding freed memory (unless
/// `--keep-freed-memory`): glibc keeps freed buffers for reuse, so a run's peak resident memory
/// rose above what it ever holds at once, beyond the estimate that `--memory-limit` checks
/// (lego, `results/memory.md`). Three parts:
/// - while loading, an mmap threshold fixed at 128 KiB (`LOADING_MMAP_THRESHOLD`): the
///   images' large transient buffers (800×800 in f32, in every loader thread) get their own
///   mappings, returned when freed;
/// - from the first iteration, the threshold fixed at 32 MiB (`TRAINING_MMAP_THRESHOLD`,
///   where glibc's own rising threshold ends): the buffers the networks allocate in every
///   iteration are reused from the heap (an mmap and fresh pages for each cost 9 % more CPU
///   time on lego at 34 535 Gaussians);
/// - `malloc_trim` after the first iteration, whenever the Gaussian count changed
///   (densification and pruning reallocate every per-Gaussian buffer) and before each
///   checkpoint write (the peak; the networks' per-iteration buffers are free then).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
mod allocator {
    /// The mmap threshold while loading (glibc's initial one).
    pub const LOADING_MMAP_THRESHOLD: libc::c_int = 128 << 10;
    /// The mmap threshold while training (glibc's `DEFAULT_MMAP_THRESHOLD_MAX` on 64 bits).
    pub const TRAINING_MMAP_THRESHOLD: libc::c_int = 32 << 20;

    /// Fixes glibc's mmap threshold at `bytes`, and its trim threshold (free memory at the top
    /// of the heap beyond which `free` returns it) at twice that, as glibc's rising threshold
    /// would: a fixed mmap threshold leaves the trim threshold at 128 KiB, and every
    /// iteration's buffers at the top of the heap were then returned and faulted in again
    /// (lego, 200×200: 5.3 M page faults against 0.35 M).
    pub fn mmap_threshold(bytes: libc::c_int) {
        // SAFETY: mallopt takes two integers and only changes the allocator's tuning: no pointer
        // arguments, and glibc serialises it with the arenas' locks, so it is sound at any time.
        // Its return value (1 = accepted) changes nothing here: glibc's default stays otherwise.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, bytes);
            libc::mallopt(libc::M_TRIM_THRESHOLD, bytes.saturating_mul(2));
        }
    }

    /// Returns every whole free page of every arena (the loader threads' included) and the top
    /// of the heap to the system.
    pub fn trim() {
        // SAFETY: malloc_trim takes an integer and only walks the allocator's own free lists
        // under its arenas' locks, returning free pages to the kernel: no pointer arguments, and
        // no memory the program holds is touched, so it is sound at any time.
        unsafe {
            libc::malloc_trim(0);
        }
    }
}

/// Elsewhere the allocator is left as it is.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
mod allocator {
    pub const LOADING_MMAP_THRESHOLD: i32 = 0;
    pub const TRAINING_MMAP_THRESHOLD: i32 = 0;
    pub fn mmap_threshold(_bytes: i32) {}
    pub fn trim() {}
}

/// Whether the run has a memory limit: `--memory-limit`, or on `--resume` the one recorded in
/// the run's `config.json` (an unreadable file is reported by the resume itself).
fn has_memory_limit(args: &TrainArgs) -> bool {
    if args.memory_limit.is_some() {
        return true;
    }
    args.resume
        && std::fs::read(evogs_train::run::RunPaths::new(&args.out).config())
            .ok()
            .and_then(|b| serde_json::from_slice::<evogs_train::run::RunFile>(&b).ok())
            .is_some_and(|run| run.train.memory_limit.is_some())
}

/// Runs `evogs train`.
pub fn run_train(args: &TrainArgs) -> Result<TrainSummary> {
    let release = !args.keep_freed_memory;
    if release {
        allocator::mmap_threshold(allocator::LOADING_MMAP_THRESHOLD);
    } else if has_memory_limit(args) {
        anyhow::bail!(
            "--keep-freed-memory: {} has a memory limit, which the estimate can only keep with \
             freed memory returned",
            evogs_train::run::RunPaths::new(&args.out)
                .config()
                .display()
        );
    }
    let config = config_from_args(args)?;
    let request = TrainRequest {
        data: args.data.clone().unwrap_or_else(|| PathBuf::from(".")),
        out: args.out.clone(),
        config,
        resume: args.resume,
        stop_after: args.stop_after,
        resume_backend: if args.resume { args.backend } else { None },
        resume_net_backend: if args.resume { args.net_backend } else { None },
    };
    if !args.resume {
        // Say which layout was detected (reading the cameras again inside `train` is cheap: no
        // images are loaded here).
        let dataset = evogs_train::data::open_dataset(&request.data, request.config.time_from)?;
        println!("dataset: {}", dataset.summary());
        if let Some(warning) = dataset.camera_warning() {
            eprintln!("warning: {warning}");
        }
        make_room(&request.out, args.force)?;
    }
    let terminal = std::io::stderr().is_terminal();
    let bar = if terminal {
        ProgressBar::new(0)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} {per_sec} ETA {eta} | {msg}")
            .context("progress bar template")?,
    );
    let started = Instant::now();
    let mut first = None;
    let mut said_backend = false;
    // The estimate at the most Gaussians the run had, to compare with the measured peak.
    let mut peak: Option<(usize, u64)> = None;
    let mut motion: Option<MotionReport> = None;
    // The Gaussian count at the last `allocator::trim` (none before the first iteration).
    let mut trimmed_at: Option<usize> = None;
    let summary = train(&request, &mut |report, trainer| {
        let checkpoint = checkpoint_follows(trainer.config(), report);
        if release && (checkpoint || trimmed_at != Some(report.gaussians)) {
            if trimmed_at.is_none() {
                allocator::mmap_threshold(allocator::TRAINING_MMAP_THRESHOLD);
            }
            allocator::trim();
            trimmed_at = Some(report.gaussians);
        }
        if !said_backend {
            println!("{}", trainer.backend());
            println!("{}", trainer.network());
            println!("{}", trainer.loss_place());
            let n = report.gaussians;
            let mut line = trainer.memory_estimate().summary(n);
            if let Some(cap) = trainer.max_gaussians() {
                line += &format!("; densification stops at {cap} Gaussians");
            }
            println!("{line}");
            said_backend = true;
        }
        if peak.is_none_or(|(n, _)| report.gaussians > n) {
            peak = Some((
                report.gaussians,
                trainer.memory_estimate().at(report.gaussians),
            ));
        }
        if args.motion_report
            && let Some(stats) = trainer.motion_stats()
        {
            motion
                .get_or_insert_with(|| MotionReport::for_run(trainer))
                .add(stats);
        }
        // The bar and the ETA follow the schedule (a budget run's steps are not its length).
        let total = trainer.config().iterations;
        let at = report.schedule_iteration;
        let (start, start_at) = *first.get_or_insert((report.iteration - 1, at.saturating_sub(1)));
        bar.set_length(total);
        bar.set_position(at);
        let msg = format!(
            "loss {:.4} PSNR {:.2} dB, {} Gaussians",
            report.loss, report.psnr, report.gaussians
        );
        bar.set_message(msg.clone());
        let every = (total / 20).clamp(1, 500);
        if !terminal && (report.iteration.is_multiple_of(every) || at == total) {
            let elapsed = started.elapsed().as_secs_f64().max(1e-9);
            let rate = report.iteration.saturating_sub(start) as f64 / elapsed;
            let eta = (total - at) as f64 / ((at - start_at) as f64 / elapsed).max(1e-9);
            let position = if trainer.config().budget.is_some() {
                format!("{} (schedule {at}/{total})", report.iteration)
            } else {
                format!("{}/{total}", report.iteration)
            };
            eprintln!("iteration {position}: {msg}, {rate:.2} it/s, ETA {eta:.0} s");
        }
        if let Some(m) = motion.as_mut()
            && report.iteration.is_multiple_of(every)
            && m.samples() > 0
        {
            bar.suspend(|| eprint!("{}", m.table()));
            m.reset();
        }
    })?;
    bar.finish_and_clear();
    if let (Some((n, estimate)), Some(measured)) = (peak, evogs_train::train_log::peak_rss_bytes())
    {
        use evogs_train::memory::human_bytes;
        let error = 100.0 * (estimate as f64 / measured as f64 - 1.0);
        println!(
            "memory: measured peak {}; the estimate at the most Gaussians ({n}) was {}, {:.1}% {} it",
            human_bytes(measured),
            human_bytes(estimate),
            error.abs(),
            if error < 0.0 { "below" } else { "above" }
        );
    }
    if args.gain_report {
        match &summary.gain {
            Some(g) => print!("{}", gain_table(g)),
            None => println!(
                "gain K: no gain-stage steps in the last quarter (EvoGS with evolution only)"
            ),
        }
    }
    Ok(summary)
}
