//! The command line's top (clap derive): [`Cli`] and its subcommands, each with the arguments
//! its own module declares (`train_cmd::TrainArgs`, …; flags several share are in
//! `shared_args`). Every value is parsed once, by clap, into the library's own type (its
//! `FromStr`, a one-word parser listing the type's spellings, or a `ValueEnum` wrapper): the
//! spellings live beside the types.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Dynamic 3D Gaussian Splatting with EvoGS: train on a dynamic scene (any detected dataset
/// layout), evaluate, render, export, view.
#[derive(Debug, Parser)]
#[command(name = "evogs", version)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
// Parsed once per process: the size of the largest variant does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Train a dynamic scene on a dataset (D-NeRF, nerfies, Neu3D, COLMAP, nerfstudio) into a run
    /// directory.
    Train(crate::train_cmd::TrainArgs),
    /// Evaluate a run on a split: PSNR, SSIM, LPIPS, flicker, jitter (JSON and markdown).
    Eval(crate::eval_cmd::EvalArgs),
    /// Render Gaussians (a trained run at a time, a 3DGS PLY, or the built-in demo scene) to PNG.
    Render(crate::render::RenderArgs),
    /// Render a trained run along a camera path into an mp4, a GIF or PNG frames.
    Video(crate::video_cmd::VideoArgs),
    /// Generate a procedural dynamic scene (D-NeRF layout) with its ground truth.
    Synth(crate::synth_cmd::SynthArgs),
    /// Export a run's deformed Gaussians at a time, or a sequence, as 3DGS PLY, compressed PLY or
    /// .splat.
    Export(crate::export_cmd::ExportArgs),
    /// Train the baseline and EvoGS on the built-in synthetic scene and compare them (no files
    /// needed).
    Demo(crate::demo_cmd::DemoArgs),
    /// Run the paper's ablation ladder at equal iterations on one dataset (table, JSON, plot).
    Ablate(crate::ablate_cmd::AblateArgs),
    /// Train and evaluate D-NeRF scenes × methods: one table with the published figures, a
    /// PSNR-against-time plot, a picture per scene.
    Bench(crate::bench_cmd::BenchArgs),
    /// Plot a run's training log (loss, PSNR, Gaussians against the iteration) as a PNG.
    Plot(PlotArgs),
    /// Turn a video (or an image folder) into a dataset: ffmpeg frames, COLMAP poses on the CPU.
    Prepare(crate::prepare_cmd::PrepareArgs),
    /// Look at a run, or two side by side, in a web browser (orbit, time slider, ground truth).
    View(crate::view_cmd::ViewArgs),
}

/// Arguments of `evogs plot`.
#[derive(Debug, Args)]
pub struct PlotArgs {
    /// Run directory (holds `train_log.jsonl`).
    #[arg(value_name = "RUN")]
    pub run: PathBuf,

    /// Output PNG [default: RUN/train_log.png].
    #[arg(long, value_name = "FILE.png")]
    pub out: Option<PathBuf>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clap_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }

    /// EvoGS's flags default to `EvoSettings::default()`, which every preset keeps: so a run
    /// without them trains with its preset's EvoGS settings, and the help's defaults are true for
    /// every preset.
    #[test]
    fn presets_share_the_evogs_defaults() {
        for preset in evogs_train::Preset::ALL {
            let config = evogs_train::TrainConfig::preset(preset);
            assert_eq!(
                config.backbones.evogs,
                evogs_backbones::EvoSettings::default(),
                "{preset}"
            );
            let cli = Cli::parse_from([
                "evogs",
                "train",
                "--data",
                "d",
                "--out",
                "o",
                "--method",
                "evogs",
                "--preset",
                &preset.to_string(),
            ]);
            let Command::Train(args) = cli.command else {
                unreachable!("train parses as train");
            };
            assert_eq!(
                crate::train_cmd::config_from_args(&args)
                    .unwrap()
                    .backbones
                    .evogs,
                config.backbones.evogs,
                "{preset}"
            );
        }
    }
}
