//! `evogs-cli`: the `evogs` command line.
//!
//! What it is: argument parsing ([`args`]), the `render` command ([`render`]) that draws a 3DGS
//! PLY from a nerfies camera to a PNG, and the built-in procedural scene ([`demo_scene`]) that
//! `render` draws when no PLY and camera are given.
//!
//! What it is not: a trainer or a dataset tool (yet); every file format lives in `evogs-io`,
//! rendering in `splat-raster`. Errors are `anyhow` here and are shown as one line.

pub mod args;
pub mod demo_scene;
pub mod render;

pub use args::{Cli, Command, RenderArgs};
