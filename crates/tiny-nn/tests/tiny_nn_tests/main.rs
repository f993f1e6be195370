//! tiny-nn's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p tiny-nn --test tiny_nn_tests <module>::`.

mod adam;
mod common;
mod encoders;
#[cfg(feature = "wgpu")]
mod gpu_adam;
#[cfg(feature = "wgpu")]
mod gpu_deform;
#[cfg(feature = "wgpu")]
mod gpu_mlp;
mod grid4d;
mod hashgrid;
mod hexfield;
mod hexplane;
mod mlp;
mod nets;
mod param_count;
