//! The `evogs` binary: parses arguments, runs the command, prints errors as one line.

use std::process::ExitCode;

use clap::Parser;
use clap::error::ErrorKind;
use evogs_cli::error_line::{one_line, with_causes};
use evogs_cli::eval_cmd::run_eval;
use evogs_cli::export_cmd::run_export;
use evogs_cli::render::run_render;
use evogs_cli::train_cmd::run_train;
use evogs_cli::{Cli, Command};

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => {
            if matches!(
                err.kind(),
                ErrorKind::DisplayHelp | ErrorKind::DisplayVersion
            ) {
                // Help and version go to stdout with success.
                let _ = err.print();
                return ExitCode::SUCCESS;
            }
            if err.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                let _ = err.print();
                return ExitCode::from(2);
            }
            // clap's message without the usage and the hint to try --help, joined into one line.
            let rendered = err.render().to_string();
            let message = rendered
                .split("\n\nUsage:")
                .next()
                .unwrap_or("")
                .split("\n\nFor more information")
                .next()
                .unwrap_or("");
            let message = message
                .trim()
                .strip_prefix("error: ")
                .unwrap_or(message.trim());
            let words: Vec<&str> = message.split_whitespace().collect();
            eprintln!("evogs: {} (see --help)", one_line(&words.join(" ")));
            return ExitCode::from(2);
        }
    };
    let result = match &cli.command {
        Command::Train(args) => run_train(args).map(|s| {
            println!(
                "trained {} iterations ({} in this process, {:.2} it/s, network width {}): \
                 loss {:.4}, PSNR {:.2} dB, {} Gaussians; wrote {}",
                s.iteration,
                s.iterations_this_process,
                s.iterations_per_second,
                s.net_width,
                s.last_loss,
                s.last_psnr,
                s.gaussians,
                args.out.display()
            );
            if let Some(b) = &s.budget {
                println!(
                    "budget: spent {:.1} of {}; schedule iteration {} of {}",
                    b.spent_seconds,
                    b.budget.describe(),
                    b.schedule_iteration,
                    s.iterations
                );
                if b.lagged > 0 {
                    eprintln!(
                        "warning: the schedule lagged behind the budget: the last step took {} \
                         schedule iterations more than a step may; a lower --iterations (near \
                         the {} steps taken) fits the budget",
                        b.lagged, s.iteration
                    );
                }
            }
            println!("time per phase:\n{}", s.phases);
            if let Some(t) = &s.traffic_per_iteration {
                println!("host-device traffic per iteration: {t}");
            }
            if let Some(d) = s.device_ms_per_iteration.as_ref().filter(|d| !d.is_empty()) {
                let spans: Vec<String> = d
                    .iter()
                    .map(|(label, ms)| format!("{label} {ms:.3} ms"))
                    .collect();
                println!(
                    "device time per iteration (GPU timestamps): {}",
                    spans.join(", ")
                );
            }
        }),
        Command::Eval(args) => run_eval(args).map(|r| {
            if r.non_finite_views > 0 {
                eprintln!(
                    "evogs eval: warning: non-finite deformed Gaussians at {} of the rendered \
                     times (at most {} at one); those renders are not trustworthy",
                    r.non_finite_views, r.non_finite_gaussians
                );
            }
            println!(
                "{} split: mean PSNR {:.2} dB, mean SSIM {:.4} over {} images; wrote {}",
                r.split,
                r.mean_psnr,
                r.mean_ssim,
                r.images.len(),
                args.run.display()
            );
        }),
        Command::Export(args) => run_export(args).map(|(files, n)| {
            println!(
                "wrote {} ({files} file(s), {n} Gaussians in the first)",
                args.out.display()
            );
        }),
        Command::Render(args) => run_render(args).map(|report| {
            for warning in &report.warnings {
                eprintln!("evogs: warning: {}", one_line(warning));
            }
            println!("{}", report.stats);
            println!("{}", report.backend);
            println!(
                "wrote {} ({}x{})",
                args.out.display(),
                report.width,
                report.height
            );
        }),
        Command::Video(args) => evogs_cli::video_cmd::run_video(args).map(|r| {
            println!("{}", r.backend);
            println!(
                "wrote {} ({} frames, {}x{})",
                args.out.display(),
                r.frames,
                r.width,
                r.height
            );
        }),
        Command::Demo(args) => evogs_cli::demo_cmd::run_demo(args).map(|(n, rows)| {
            print!("{}", evogs_cli::demo_cmd::table(n, &rows));
            print!("{}", evogs_cli::demo_cmd::where_to_look(&args.out));
            println!("wrote {}", args.out.display());
        }),
        Command::Ablate(args) => evogs_cli::ablate_cmd::run_ablate(args).map(|results| {
            println!(
                "ran {} rows; wrote {}",
                results.len(),
                args.out.join("ablation.md").display()
            );
        }),
        Command::Bench(args) => evogs_cli::bench_cmd::run_bench_cmd(args).map(|runs| {
            println!(
                "ran {} runs; wrote {}",
                runs.len(),
                args.out.join("bench.md").display()
            );
        }),
        Command::Plot(args) => {
            let out = args
                .out
                .clone()
                .unwrap_or_else(|| args.run.join("train_log.png"));
            evogs_experiments::train_plot::plot_run(&args.run, &out)
                .map(|n| println!("plotted {n} log lines; wrote {}", out.display()))
                .map_err(anyhow::Error::from)
        }
        Command::Prepare(args) => evogs_cli::prepare_cmd::run_prepare(args)
            .map(|summary| println!("{}", evogs_cli::prepare_cmd::report_line(args, &summary))),
        Command::View(args) => evogs_cli::view_cmd::start_view(args).map(|viewer| {
            if let Some(w) = evogs_cli::view_cmd::host_warning(args.host) {
                eprintln!("evogs: {w}");
            }
            for info in viewer.infos() {
                println!(
                    "loaded {}: {} Gaussians, iteration {}, {}",
                    info.name, info.gaussians, info.iteration, info.backend
                );
            }
            println!("viewer at {} (Ctrl-C stops it)", viewer.url());
            use std::io::Write;
            let _ = std::io::stdout().flush();
            viewer.wait();
        }),
        Command::Synth(args) => evogs_cli::synth_cmd::run_synth(args)
            .map(|summary| println!("{}", evogs_cli::synth_cmd::report_line(args, &summary))),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("evogs: error: {}", one_line(&with_causes(&err)));
            ExitCode::FAILURE
        }
    }
}
