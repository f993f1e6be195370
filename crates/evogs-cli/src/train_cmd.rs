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

use crate::args::TrainArgs;

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
    config.backbone = args.backbone;
    let e = &mut config.evogs;
    if let Some(v) = args.gain {
        e.evo.gain = v;
    }
    if let Some(v) = args.history {
        e.evo.history = v;
    }
    if let Some(v) = args.densify {
        e.densify = v;
    }
    if let Some(v) = args.buffer {
        e.evo.storage = v;
    }
    if let Some(v) = args.net_precision {
        e.net_precision = v;
    }
    if let Some(v) = args.components {
        e.evo.layout = v;
    }
    if let Some(v) = args.motion_floor {
        e.evo.motion_floor = v;
    }
    if let Some(v) = args.grid_lr_scale {
        e.grid_lr_scale = v;
    }
    if let Some(v) = args.psi_lr {
        e.psi_lr = Some(v);
    }
    if let Some(v) = args.bspline_controls {
        e.bspline_controls = v;
    }
    if let Some(v) = args.bspline_width {
        e.bspline_width = v;
    }
    if let Some(v) = &args.triplane_resolutions {
        e.triplane_resolutions.clone_from(v);
    }
    if let Some(v) = args.triplane_combine {
        e.triplane_combine = v;
    }
    if let Some(v) = args.triplane_channels {
        e.triplane_channels = v;
    }
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
    config.seed = args.seed;
    config.backend = args.backend.unwrap_or_default();
    config.validate()?;
    Ok(config)
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
    };
    if !args.resume {
        // Say which layout was detected (reading the cameras again inside `train` is cheap: no
        // images are loaded here).
        let dataset = evogs_train::data::open_dataset(&request.data, request.config.time_from)?;
        println!("dataset: {}", dataset.summary());
        if let Some(warning) = dataset.camera_warning() {
            eprintln!("warning: {warning}");
        }
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
        println!(
            "memory: estimate {} at the most Gaussians ({n}), measured peak {} ({:+.1}%)",
            human_bytes(estimate),
            human_bytes(measured),
            100.0 * (estimate as f64 / measured as f64 - 1.0)
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
