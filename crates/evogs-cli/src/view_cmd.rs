//! `evogs view`: serves the web viewer of one run, or of two side by side (`evogs-view`).

use std::net::IpAddr;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use evogs_view::http::Limits;
use evogs_view::{RunningViewer, ViewOptions};

use crate::shared_args::RasterArgs;

/// Arguments of `evogs view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// Run directory to look at.
    #[arg(value_name = "RUN")]
    pub run: PathBuf,

    /// A second run, shown beside the first with the same camera and time (e.g. the baseline).
    #[arg(value_name = "RUN_B")]
    pub run_b: Option<PathBuf>,

    /// Port to listen on (0: any free port; the URL printed says which).
    #[arg(
        long,
        allow_negative_numbers = true,
        default_value_t = 8080,
        value_parser = clap::value_parser!(u16).range(0..)
    )]
    pub port: u16,

    /// Address to listen on. Anything but a loopback address exposes the runs to the network
    /// (a warning is printed); for a remote machine prefer `ssh -L PORT:127.0.0.1:PORT`.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: IpAddr,

    /// The rasterizer backend.
    #[command(flatten)]
    pub raster: RasterArgs,

    /// Reload a run when its files change: watch a training run (loaded from its checkpoint
    /// while it trains, from its end-of-run files once they are written).
    #[arg(long)]
    pub watch: bool,
}

/// The warning printed for a non-loopback `--host`, if any.
pub fn host_warning(host: IpAddr) -> Option<String> {
    (!host.is_loopback()).then(|| {
        format!(
            "warning: listening on {host}, not a loopback address: anyone who can reach this \
             machine can see the runs; prefer the default 127.0.0.1 with `ssh -L`"
        )
    })
}

/// Loads the runs and starts the server (the caller prints the URL and waits).
pub fn start_view(args: &ViewArgs) -> Result<RunningViewer> {
    let options = ViewOptions {
        runs: std::iter::once(args.run.clone())
            .chain(args.run_b.clone())
            .collect(),
        host: args.host,
        port: args.port,
        backend: args.raster.backend,
        watch: args.watch,
        limits: Limits::default(),
    };
    Ok(evogs_view::start(&options)?)
}
