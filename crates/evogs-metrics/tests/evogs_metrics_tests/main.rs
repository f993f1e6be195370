//! evogs-metrics's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p evogs-metrics --test evogs_metrics_tests <module>::`.

mod common;
mod fast_loss;
#[cfg(feature = "wgpu")]
mod gpu_loss;
mod loss;
mod lpips_reference;
