//! splat-raster's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p splat-raster --test splat_raster_tests <module>::`.

mod backend;
mod common;
#[cfg(feature = "wgpu")]
mod gpu_parity;
mod gradients;
mod hard_cases;
mod invariants;
mod reference;
mod snapshot;
