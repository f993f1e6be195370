//! `evogs synth`: generate a procedural dynamic scene in the D-NeRF layout, with ground truth.

use std::path::PathBuf;

use anyhow::Context;
use clap::builder::PossibleValue;
use clap::{Args, ValueEnum};
use evogs_synth::{Preset, SceneSpec, SceneSummary, generate, write_dnerf};

/// A preset as a command-line value; names and help come from the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PresetArg(pub Preset);

const PRESET_ARGS: [PresetArg; 4] = [
    PresetArg(Preset::Rigid),
    PresetArg(Preset::Wave),
    PresetArg(Preset::Jump),
    PresetArg(Preset::Mixed),
];

impl ValueEnum for PresetArg {
    fn value_variants<'a>() -> &'a [Self] {
        &PRESET_ARGS
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()).help(self.0.help()))
    }
}

/// Arguments of `evogs synth`.
#[derive(Debug, Args)]
#[command(
    after_help = "Writes DIR/transforms_{train,test,val}.json and DIR/{train,test,val}/r_NNN.png \
                  (RGBA), the canonical Gaussians DIR/canonical.ply, the per-frame ground truth \
                  DIR/ground_truth.safetensors (times, means, and rotations or SH DC only when \
                  the scene changes them) and the index DIR/scene.json. Same seed, same files."
)]
pub struct SynthArgs {
    /// Which scene: each preset enables only the effects listed.
    #[arg(long, value_name = "NAME")]
    pub preset: PresetArg,

    /// Output directory (created if missing; files are written atomically).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Random seed (cameras and colour palette).
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub seed: u64,

    /// Image width and height in pixels.
    #[arg(long, value_name = "N", default_value_t = 128,
          value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub size: u32,

    /// Training frames (times k/(F-1)); test and val get F/5 each (at least 2).
    #[arg(long, value_name = "F", default_value_t = 40,
          value_parser = clap::value_parser!(u32).range(3..=10000))]
    pub frames: u32,
}

/// Generates and writes the scene; returns its summary.
pub fn run_synth(args: &SynthArgs) -> anyhow::Result<SceneSummary> {
    let spec = SceneSpec::preset(args.preset.0)
        .with_size(args.size)
        .with_frames(args.frames as usize);
    let scene = generate(&spec, args.seed)
        .with_context(|| format!("generating preset `{}`", args.preset.0.name()))?;
    write_dnerf(&scene, &args.out)
        .with_context(|| format!("writing the scene to {}", args.out.display()))?;
    Ok(SceneSummary::of(&scene))
}

/// One line describing what was written.
pub fn report_line(args: &SynthArgs, summary: &SceneSummary) -> String {
    let frames: Vec<String> = summary
        .splits
        .iter()
        .map(|s| s.frames.to_string())
        .collect();
    format!(
        "wrote {}: {} Gaussians, {} frames (train/test/val) at {}x{}, effects: {}",
        args.out.display(),
        summary.gaussians,
        frames.join("/"),
        summary.image_size,
        summary.image_size,
        summary.effects.join(", ")
    )
}
