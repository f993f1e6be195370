//! The `evogs` binary: parses arguments, runs the command, prints errors as one line.

use std::process::ExitCode;

use clap::Parser;
use clap::error::ErrorKind;
use evogs_cli::render::run_render;
use evogs_cli::{Cli, Command};

/// One line: line breaks in a message become spaces.
fn one_line(text: &str) -> String {
    text.trim().replace(['\n', '\r'], " ")
}

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
            // First line of clap's message (the rest is a hint to try --help).
            let rendered = err.render().to_string();
            let first = rendered
                .lines()
                .find(|l| !l.trim().is_empty())
                .unwrap_or("");
            let message = first.strip_prefix("error: ").unwrap_or(first);
            eprintln!("evogs: {} (see --help)", one_line(message));
            return ExitCode::from(2);
        }
    };
    let result = match &cli.command {
        Command::Render(args) => run_render(args).map(|report| {
            for warning in &report.warnings {
                eprintln!("evogs: warning: {}", one_line(warning));
            }
            println!("{}", report.stats);
            println!(
                "wrote {} ({}x{})",
                args.out.display(),
                report.width,
                report.height
            );
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("evogs: error: {}", one_line(&format!("{err:#}")));
            ExitCode::FAILURE
        }
    }
}
