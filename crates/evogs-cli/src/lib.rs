//! `evogs-cli`: the `evogs` command line.
//!
//! What it is: argument parsing ([`args`]: the subcommands; [`shared_args`]: flags several
//! share) and one thin module per subcommand, each declaring its own arguments: `train`
//! ([`train_cmd`]: settings from the flags, progress bar), `eval` ([`eval_cmd`]), `export`
//! ([`export_cmd`]), `demo` ([`demo_cmd`]: baseline vs EvoGS on the embedded synthetic scene), `ablate`
//! ([`ablate_cmd`]: the paper's ablation ladder), `bench` ([`bench_cmd`]: the D-NeRF benchmark), and `render` ([`render`]: a 3DGS PLY from a nerfies camera, the built-in
//! procedural scene of [`demo_scene`], or a trained run at a time or a time sweep via
//! [`render::render_run`]), `synth` ([`synth_cmd`]: procedural scenes in the D-NeRF layout), `video` ([`video_cmd`]: a
//! run along a camera path into an mp4, a GIF or PNG frames), and `prepare` ([`prepare_cmd`]: a video or image
//! folder to a COLMAP dataset, via `evogs-prepare`), and `view` ([`view_cmd`]: the web viewer of
//! `evogs-view`).
//!
//! What it is not: a trainer or a scene generator; training lives in `evogs-train`, the
//! deformation backbones in `evogs-backbones`, evaluation, rendering and export of a run in
//! `evogs-eval`, synthetic scenes in `evogs-synth`, file formats in `evogs-io`, rasterization in
//! `splat-raster`. Errors are `anyhow`
//! here and are shown as one line.

pub mod ablate_cmd;
pub mod args;
pub mod bench_cmd;
pub mod demo_cmd;
pub mod demo_scene;
pub mod error_line;
pub mod eval_cmd;
pub mod export_cmd;
pub mod prepare_cmd;
pub mod progress;
pub mod render;
pub mod shared_args;
pub mod synth_cmd;
pub mod train_cmd;
pub mod video_cmd;
pub mod view_cmd;

pub use args::{Cli, Command};
pub use eval_cmd::EvalArgs;
pub use export_cmd::ExportArgs;
pub use render::RenderArgs;
pub use train_cmd::TrainArgs;
