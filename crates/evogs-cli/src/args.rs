//! Command-line arguments (clap derive). Every value is parsed once, by clap, into the
//! library's own type (its `FromStr` or a `ValueEnum` wrapper): the spellings live beside the types.

use std::path::PathBuf;

use clap::builder::PossibleValue;
use clap::{Args, Parser, Subcommand, ValueEnum};
use evogs_io::TimeFrom;
use evogs_video::camera_path::CameraSpec;
use splat_raster::BackendChoice;

/// A time rule as a command-line value; names and help come from the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimeFromArg(pub TimeFrom);

/// Every rule, as [`TimeFrom::ALL`] lists them.
const TIME_FROM_ARGS: [TimeFromArg; TimeFrom::ALL.len()] = {
    let mut args = [TimeFromArg(TimeFrom::ALL[0]); TimeFrom::ALL.len()];
    let mut i = 1;
    while i < args.len() {
        args[i] = TimeFromArg(TimeFrom::ALL[i]);
        i += 1;
    }
    args
};

impl ValueEnum for TimeFromArg {
    fn value_variants<'a>() -> &'a [Self] {
        &TIME_FROM_ARGS
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()).help(self.0.help()))
    }
}

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
    Train(TrainArgs),
    /// Evaluate a run on a split: PSNR, SSIM, LPIPS, flicker, jitter (JSON and markdown).
    Eval(EvalArgs),
    /// Render Gaussians (a trained run at a time, a 3DGS PLY, or the built-in demo scene) to PNG.
    Render(RenderArgs),
    /// Render a trained run along a camera path into an mp4, a GIF or PNG frames.
    Video(crate::video_cmd::VideoArgs),
    /// Generate a procedural dynamic scene (D-NeRF layout) with its ground truth.
    Synth(crate::synth_cmd::SynthArgs),
    /// Export a run's deformed Gaussians at a time, or a sequence, as 3DGS PLY, compressed PLY or
    /// .splat.
    Export(ExportArgs),
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

/// A time budget on the command line (`evogs train`, `bench`, `ablate`).
#[derive(Debug, Args)]
pub struct BudgetArgs {
    /// Train for this much time instead of a number of iterations (180s, 3m, 2m30s, 1h): the
    /// schedule (warm-up, SH steps, lr decays, densification, opacity resets) is the preset's,
    /// or --iterations', mapped onto the share of the budget spent, so it ends when the budget
    /// is spent. Counts the training loop, not the loading or evaluations; recorded in
    /// config.json and train_metrics.json with the iterations reached [default: no budget].
    #[arg(long, value_name = "DURATION", value_parser = parse_time_budget, allow_hyphen_values = true)]
    pub time_budget: Option<f64>,

    /// The clock --time-budget is measured on: cpu (the process's CPU time, all threads summed:
    /// fair on a machine shared with other jobs; with T threads a budget lasts about 1/T of it
    /// in wall time) or wall (wall-clock time) [default: cpu].
    #[arg(long, value_name = "cpu|wall", requires = "time_budget")]
    pub budget_clock: Option<evogs_train::budget::BudgetClock>,
}

impl BudgetArgs {
    /// The budget the flags ask for.
    pub fn budget(&self) -> Option<evogs_train::budget::TimeBudget> {
        self.time_budget
            .map(|seconds| evogs_train::budget::TimeBudget {
                seconds,
                clock: self.budget_clock.unwrap_or_default(),
            })
    }
}

/// `--time-budget`: a duration ([`evogs_train::budget::parse_duration`]).
fn parse_time_budget(text: &str) -> Result<f64, String> {
    evogs_train::budget::parse_duration(text)
}

/// Arguments of `evogs train`.
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Dataset directory: D-NeRF, nerfies, Neu3D, COLMAP (`evogs prepare` writes one) or
    /// nerfstudio; the layout is detected.
    #[arg(long, value_name = "DIR", required_unless_present = "resume")]
    pub data: Option<PathBuf>,

    /// Times of frames whose dataset stores none (COLMAP, nerfstudio without `time`); see the
    /// README's Datasets section for the names `name` accepts [default: order].
    #[arg(long, value_name = "RULE")]
    pub time_from: Option<TimeFromArg>,

    /// Run directory to write (config, checkpoint, PLY, weights, metrics).
    #[arg(long, value_name = "RUN")]
    pub out: PathBuf,

    /// Deformation method: baseline (D-3DGS) or evogs (EvoGS(D-3DGS): observation network Φ
    /// at half the width, evolution state, gain network Ψ).
    #[arg(long, default_value = "baseline", value_name = "baseline|evogs")]
    pub method: evogs_train::Method,

    /// Deformation backbone: d3dgs (Deformable-3D-Gaussians' MLP), 4dgs (4DGaussians'
    /// HexPlane field with its regularisers) or grid4d (Grid4D's 4D decomposed hash grids with
    /// directional attention). With --method evogs, 4dgs's and grid4d's fields become Φ at half
    /// their width.
    #[arg(long, default_value = "d3dgs", value_name = "d3dgs|4dgs|grid4d")]
    pub backbone: evogs_train::BackboneKind,

    /// EvoGS gain K: learned (Ψ), or fixed at a number in [0, 1] (0 = prior only, 1 =
    /// observation only) [default: learned].
    #[arg(long, value_name = "learned|0|0.5|1")]
    pub gain: Option<evogs_backbones::Gain>,

    /// EvoGS history: from the buffer of corrected states, or re-queried from Φ ("without
    /// buffer") [default: buffer].
    #[arg(long, value_name = "buffer|requery")]
    pub history: Option<evogs_backbones::HistoryMode>,

    /// EvoGS densification: standard 3DGS, + uncertainty trigger, + deformation-aware
    /// clone/split [default: trigger+deform].
    #[arg(long, value_name = "standard|trigger|trigger+deform")]
    pub densify: Option<evogs_backbones::DensifyPolicy>,

    /// EvoGS buffer storage [default: f32].
    #[arg(long, value_name = "f32|f16")]
    pub buffer: Option<evogs_backbones::Storage>,

    /// EvoGS Φ storage precision [default: f32].
    #[arg(long, value_name = "f32|f16")]
    pub net_precision: Option<evogs_backbones::Precision>,

    /// EvoGS deformation components, comma-separated [default: pos,rot,scale]; opacity adds
    /// to the opacity logit, colour to the SH DC (EvoGS only; the baseline refuses them).
    #[arg(long, value_name = "pos,rot,scale[,opacity,colour]")]
    pub components: Option<evogs_backbones::Layout>,

    /// EvoGS motion floor: below this speed per frame spacing, as a fraction of the scene
    /// extent, a Gaussian counts as still and its angular deviation θ is 0 [default: 1e-3, the
    /// trainer's; the paper's 1e-6 is far below the noise, see docs/DESIGN.md §4.7].
    #[arg(long, value_name = "F", allow_negative_numbers = true)]
    pub motion_floor: Option<f32>,

    /// EvoGS: factor on the network learning rate for Φ's tri-plane features and B-spline
    /// controls [default: 10, as grid-based deformation fields (4DGaussians) train their grids].
    #[arg(long, value_name = "S")]
    pub grid_lr_scale: Option<f32>,

    /// EvoGS: Ψ's own learning rate (constant, Adam) [default: 1e-3, provisional; recorded in
    /// config.json].
    #[arg(long, value_name = "LR")]
    pub psi_lr: Option<f32>,

    /// EvoGS: Φ's B-spline control vectors over the frames' time span (at least 4; more let the
    /// deformation change faster in time) [default: 16].
    #[arg(long, value_name = "M")]
    pub bspline_controls: Option<usize>,

    /// EvoGS: Φ's time features, the length of each B-spline control vector (at least 1; more
    /// give the decoder more independent curves over time) [default: 8].
    #[arg(long, value_name = "W")]
    pub bspline_width: Option<usize>,

    /// EvoGS: Φ's tri-plane resolutions, comma-separated (their features are concatenated)
    /// [default: 32,64].
    #[arg(long, value_name = "R,R", value_delimiter = ',')]
    pub triplane_resolutions: Option<Vec<usize>>,

    /// EvoGS: how Φ's three planes of a resolution are combined: concat (3C features) or product
    /// (C features, each localised in all three axes: K-Planes, 4DGaussians) [default: concat].
    #[arg(long, value_name = "concat|product")]
    pub triplane_combine: Option<evogs_backbones::PlaneCombine>,

    /// EvoGS: Φ's tri-plane channels per plane [default: 8].
    #[arg(long, value_name = "C")]
    pub triplane_channels: Option<usize>,

    /// Schedule iterations over which the deformation network's learning rate (D-3DGS's MLP, or
    /// EvoGS's Φ, its planes and controls at `--grid-lr-scale` times it) decays from 8e-4 to
    /// 1.6e-6, as D-3DGS's `deform_lr_max_steps`; counted on the run's schedule (after
    /// `--iterations`), so the schedule's length decays it over the whole run, under a time
    /// budget too [preset: paper 40000, cpu 3000, tiny 300, dnerf 40000 on its schedule of
    /// 12000, ending at ~1.2e-4].
    #[arg(long, value_name = "N", value_parser = clap::builder::RangedU64ValueParser::<u64>::new().range(1..))]
    pub net_lr_decay: Option<u64>,

    /// Width of the deformation network (D-3DGS's MLP; EvoGS's Φ decodes at half of it)
    /// [preset: paper 256, cpu and dnerf 64, tiny 32].
    #[arg(long, value_name = "W", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(2..))]
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

    /// Settings preset: paper (D-3DGS reference, width 256, 40K iterations), cpu (400×400 on
    /// 2 cores, width 64, 3K iterations), tiny (CI, width 32, 300 iterations), dnerf (the D-NeRF
    /// benchmark at 400×400: 12K iterations, network lr decay not compressed).
    #[arg(long, default_value = "cpu")]
    pub preset: evogs_train::Preset,

    /// Iterations; the preset's schedule is scaled to this count (with --time-budget: the
    /// schedule's length, which the budget is mapped onto).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub iterations: Option<u64>,

    /// The time budget.
    #[command(flatten)]
    pub budget: BudgetArgs,

    /// Image resize factor, e.g. 2 trains lego at 400×400 [preset: cpu and dnerf 2, paper 1].
    #[arg(long, value_name = "F")]
    pub downscale: Option<f32>,

    /// Seed of everything random.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Continue the run in --out from its last checkpoint (its config.json decides the rest).
    #[arg(
        long,
        conflicts_with_all = ["data", "time_from", "method", "backbone", "preset", "iterations", "downscale", "seed", "background", "gain", "history", "densify", "buffer", "net_precision", "components", "motion_floor", "grid_lr_scale", "psi_lr", "bspline_controls", "bspline_width", "triplane_resolutions", "triplane_combine", "triplane_channels", "net_lr_decay", "net_width", "max_gaussians", "max_screen_radius", "memory_limit", "checkpoint_every", "time_budget", "budget_clock"]
    )]
    pub resume: bool,

    /// Background behind the Gaussians and the images' alpha [D-3DGS default for D-NeRF: black];
    /// random: a new uniform colour each training iteration behind both (so transparency cannot
    /// pass for the background's colour), black for evaluation and renders.
    #[arg(long, value_name = "white|black|random")]
    pub background: Option<evogs_train::Background>,

    /// Rasterizer backend: cpu, wgpu (the GPU through wgpu, any adapter; an error without
    /// one) or auto (wgpu on a hardware GPU, cpu otherwise). Recorded in the run; --resume keeps
    /// the run's unless given [default: cpu].
    #[arg(long, value_name = "cpu|wgpu|auto", value_parser = parse_backend)]
    pub backend: Option<BackendChoice>,

    /// Densification never grows the Gaussians past this count (the largest gradients are
    /// densified first) [preset: dnerf 10000 for baseline, for evogs 2000000 / training views
    /// within 10000..=40000; the others no limit].
    #[arg(long, value_name = "N")]
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

    /// Write the checkpoint (what --resume continues from) every N iterations [default: the
    /// preset's, scaled with --iterations].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub checkpoint_every: Option<u64>,

    /// Stop after this many iterations in total (the run stays resumable).
    #[arg(long, value_name = "N", hide = true)]
    pub stop_after: Option<u64>,
}

/// `--memory-limit`: a byte count with an optional K, M, G or T suffix.
fn parse_memory(text: &str) -> Result<u64, String> {
    evogs_train::memory::parse_bytes(text)
}

/// Arguments of `evogs eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Run directory written by `evogs train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,

    /// Split to evaluate.
    #[arg(long, default_value = "test", value_name = "test|val|train")]
    pub split: evogs_io::Split,

    /// Times of frames whose dataset stores none, instead of the rule the run trained with.
    #[arg(long, value_name = "RULE")]
    pub time_from: Option<TimeFromArg>,

    /// Rasterizer backend: cpu, wgpu (any adapter; an error without one) or auto (wgpu on a
    /// hardware GPU, cpu otherwise).
    #[arg(long, value_name = "cpu|wgpu|auto", default_value = "cpu", value_parser = parse_backend)]
    pub backend: BackendChoice,

    /// Also report LPIPS with the VGG16 backbone (`lpips_vgg`); `lpips_alex` (AlexNet) is
    /// always reported when its weights are installed.
    #[arg(long)]
    pub lpips_vgg: bool,

    /// Directory of the LPIPS weights [default: $EVOGS_LPIPS_WEIGHTS, else
    /// ~/.cache/evogs/lpips; `scripts/lpips-weights` installs them there].
    #[arg(long, value_name = "DIR")]
    pub lpips_weights: Option<PathBuf>,
}

/// Arguments of `evogs export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Run directory written by `evogs train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,

    /// Time of one frame: training times lie in [0, 1]; any finite time is accepted (between
    /// frames, or beyond them: Φ's B-spline clamps to [0, 1], EvoGS's prior extrapolates the
    /// last frames).
    #[arg(
        long,
        value_name = "T",
        allow_negative_numbers = true,
        required_unless_present = "frames",
        conflicts_with = "frames"
    )]
    pub time: Option<f32>,

    /// A sequence of N frames at times evenly spaced over [0, 1] into the folder --out
    /// (frame_0000.ply or .compressed.ply or .splat, ... and sequence.json: format, count, files, times, Gaussians, the
    /// canonical bounds).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: Option<u32>,

    /// File format: ply (INRIA 3DGS, every SH band, f32), compressed-ply (PlayCanvas/SuperSplat's
    /// .compressed.ply: about 16 bytes a Gaussian plus 1 per higher SH coefficient, quantised in
    /// chunks of 256 in Morton order) or splat (32 bytes a Gaussian: DC colour only, 8-bit colour,
    /// opacity and rotation; sorted by volume x opacity, largest first).
    #[arg(long, default_value = "ply", value_name = "ply|compressed-ply|splat")]
    pub format: evogs_eval::render::ExportFormat,

    /// Output file (with --time) or folder (with --frames), each file written atomically.
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
}

/// Arguments of `evogs render`.
#[derive(Debug, Args)]
#[command(
    after_help = "Without --ply and --camera, renders the built-in procedural demo scene \
                        (a torus, spheres and a ground disc) from a default camera."
)]
pub struct RenderArgs {
    /// Gaussians to render: a PLY file in the 3DGS layout. Needs --camera.
    #[arg(long, value_name = "FILE", requires = "camera", conflicts_with = "run")]
    pub ply: Option<PathBuf>,

    /// A trained run to render at --time (or a --sweep of times). Needs --camera.
    #[arg(long, value_name = "RUN", requires = "camera")]
    pub run: Option<PathBuf>,

    /// Camera to render from: a nerfies camera JSON file, or dataset:SPLIT:INDEX (a camera of
    /// the run's dataset, at the run's resolution; needs --run). Needs --ply or --run.
    #[arg(long, value_name = "CAMERA")]
    pub camera: Option<CameraSpec>,

    /// Time at which to render a run: training times lie in [0, 1]; any finite time is accepted
    /// (between frames, or beyond them: Φ's B-spline clamps to [0, 1], EvoGS's prior
    /// extrapolates the last frames) [default: the dataset camera's time, else 0].
    #[arg(
        long,
        value_name = "T",
        requires = "run",
        allow_negative_numbers = true
    )]
    pub time: Option<f32>,

    /// Render N frames of a run at times evenly spaced over [0, 1] into the folder --out, plus
    /// strip.png with all frames side by side.
    #[arg(long, value_name = "N", requires = "run", value_parser = clap::value_parser!(u32).range(2..=1000))]
    pub sweep: Option<u32>,

    /// Output PNG image (a folder with --sweep), written atomically (temporary file, rename).
    #[arg(long, value_name = "IMAGE.png")]
    pub out: PathBuf,

    /// Background colour behind the Gaussians, three numbers in [0, 1] (a run uses its own).
    #[arg(long, value_name = "R,G,B", default_value = "0,0,0", value_parser = parse_background)]
    pub background: [f32; 3],

    /// Image width in pixels [demo scene default: 800]. With --camera, the camera is resized to
    /// this width (intrinsics scaled to match).
    #[arg(long, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: Option<u32>,

    /// Image height in pixels [demo scene default: 600]. With --camera, the camera is resized to
    /// this height (intrinsics scaled to match).
    #[arg(long, value_name = "PIXELS", value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: Option<u32>,

    /// Rasterizer backend: cpu, wgpu (any adapter; an error without one) or auto (wgpu on a
    /// hardware GPU, cpu otherwise).
    #[arg(long, value_name = "cpu|wgpu|auto", default_value = "cpu", value_parser = parse_backend)]
    pub backend: BackendChoice,
}

/// Parses `cpu`, `wgpu` or `auto`.
pub fn parse_backend(text: &str) -> Result<BackendChoice, String> {
    text.parse()
        .map_err(|e: splat_raster::RasterError| e.to_string())
}

/// Parses `R,G,B` with each channel a number in [0, 1].
pub fn parse_background(text: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "expected three comma-separated numbers R,G,B, found {} part(s)",
            parts.len()
        ));
    }
    let mut colour = [0f32; 3];
    for (channel, (slot, part)) in colour.iter_mut().zip(&parts).enumerate() {
        let value: f32 = part
            .parse()
            .map_err(|_| format!("channel {channel} `{part}` is not a number"))?;
        if !(0.0..=1.0).contains(&value) {
            return Err(format!("channel {channel} is {value}, outside [0, 1]"));
        }
        *slot = value;
    }
    Ok(colour)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn background_parsing() {
        assert_eq!(parse_background("0,0.5, 1").unwrap(), [0.0, 0.5, 1.0]);
        assert!(parse_background("1,1").unwrap_err().contains("three"));
        assert!(parse_background("1,x,1").unwrap_err().contains("channel 1"));
        assert!(parse_background("1,1,1.5").unwrap_err().contains("outside"));
        assert!(parse_background("NaN,0,0").unwrap_err().contains("outside"));
    }

    #[test]
    fn clap_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
