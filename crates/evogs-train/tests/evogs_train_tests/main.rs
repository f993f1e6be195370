//! evogs-train's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p evogs-train --test evogs_train_tests <module>::`.

mod allocations;
mod appearance_gradients;
mod background;
mod budget;
// Shared with evogs-cli's tests (they include it by path), so it stays at tests/common.
#[path = "../common/mod.rs"]
mod common;
mod datasets;
mod deformation_learns;
mod evogs_train;
// The device step needs the network's device form (this crate's `wgpu` feature).
#[cfg(feature = "wgpu")]
mod gpu_step;
mod motion_floor;
mod no_gaussians;
mod resume;
mod train_log;
