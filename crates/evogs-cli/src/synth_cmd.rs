//! `evogs synth`: generate a procedural dynamic scene in the D-NeRF layout, with ground truth,
//! under a capture protocol (`--protocol dnerf|monocular`) and optional capture noise.

use std::path::PathBuf;

use anyhow::Context;
use clap::builder::PossibleValue;
use clap::{Args, ValueEnum};
use evogs_synth::{CaptureNoise, Preset, Protocol, SceneSpec, SceneSummary, generate, write_dnerf};

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

/// A capture protocol as a command-line value; names and help come from the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProtocolArg(pub Protocol);

const PROTOCOL_ARGS: [ProtocolArg; 2] = [
    ProtocolArg(Protocol::Dnerf),
    ProtocolArg(Protocol::Monocular),
];

impl ValueEnum for ProtocolArg {
    fn value_variants<'a>() -> &'a [Self] {
        &PROTOCOL_ARGS
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()).help(self.0.help()))
    }
}

/// A noise level: a finite number in `0..=max`.
fn sigma(text: &str, max: f32) -> Result<f32, String> {
    let v: f32 = text
        .parse()
        .map_err(|_| format!("`{text}` is not a number"))?;
    if !(0.0..=max).contains(&v) {
        return Err(format!("{v} is outside 0..={max}"));
    }
    Ok(v)
}

fn pose_sigma(text: &str) -> Result<f32, String> {
    sigma(text, CaptureNoise::MAX_POSE)
}

fn image_sigma(text: &str) -> Result<f32, String> {
    sigma(text, CaptureNoise::MAX_IMAGE)
}

/// Arguments of `evogs synth`.
#[derive(Debug, Args)]
#[command(
    after_help = "Writes DIR/transforms_{train,test,val}.json and DIR/{train,test,val}/r_NNN.png \
                  (RGBA), the canonical Gaussians DIR/canonical.ply, the per-frame ground truth \
                  DIR/ground_truth.safetensors (times, means, and rotations or SH DC only when \
                  the scene changes them) and the index DIR/scene.json; monocular scenes add the \
                  fixed-camera sequence as the D-NeRF dataset DIR/fixed/ (its train split). Same seed, same \
                  files."
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
    #[arg(long, allow_negative_numbers = true, value_name = "N", default_value_t = 128,
          value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub size: u32,

    /// Training frames (times k/(F-1)); test and val get F/5 each (at least 2).
    #[arg(long, allow_negative_numbers = true, value_name = "F", default_value_t = 40,
          value_parser = clap::value_parser!(u32).range(3..=10000))]
    pub frames: u32,

    /// Capture protocol: where the cameras of each split are.
    #[arg(long, value_name = "NAME", default_value = "dnerf")]
    pub protocol: ProtocolArg,

    /// Pose jitter σ of the training cameras, in units of the camera distance (each coordinate
    /// of the recorded centre and look-at target; images come from the true cameras).
    #[arg(long, value_name = "σ", default_value_t = 0.0, value_parser = pose_sigma)]
    pub pose_noise: f32,

    /// Image noise σ added to the training images' object colour (straight RGB in [0, 1]).
    #[arg(long, value_name = "σ", default_value_t = 0.0, value_parser = image_sigma)]
    pub image_noise: f32,
}

/// Generates and writes the scene; returns its summary.
pub fn run_synth(args: &SynthArgs) -> anyhow::Result<SceneSummary> {
    let spec = SceneSpec::preset(args.preset.0)
        .with_size(args.size)
        .with_frames(args.frames as usize)
        .with_protocol(args.protocol.0)
        .with_noise(CaptureNoise {
            pose: args.pose_noise,
            image: args.image_noise,
        });
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
    let mut line = format!(
        "wrote {}: {} Gaussians, {} frames (train/test/val) at {}x{}, effects: {}",
        args.out.display(),
        summary.gaussians,
        frames.join("/"),
        summary.image_size,
        summary.image_size,
        summary.effects.join(", ")
    );
    if !summary.protocol.is_dnerf() {
        line += &format!(
            "; protocol {} ({} fixed-camera frames)",
            summary.protocol.name(),
            summary.fixed_camera_frames
        );
    }
    if !summary.noise.is_off() {
        line += &format!(
            "; noise: pose {}, image {}",
            summary.noise.pose, summary.noise.image
        );
    }
    line
}
