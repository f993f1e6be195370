//! evogs-cli's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of twenty, and the harness runs the tests of every module
//! on its threads together). `support` is what they share. One module alone:
//! `cargo test --workspace --locked --test evogs_cli_tests -- <module>::` (`-p evogs-cli`
//! resolves the dependencies' features for this crate alone and rebuilds some of them).

#[path = "../../../evogs-train/tests/common/mod.rs"]
mod common;
mod support;

mod ablate_cli;
mod agreement;
mod backbone_cli;
mod backend_cli;
mod bench_cli;
mod config_fixture;
mod demo_cli;
mod demo_quick;
mod evogs_cli;
mod evogs_switches;
mod faults;
mod help;
mod plot_cli;
mod prepare_cli;
mod render_cli;
mod synth_cli;
mod test_script;
mod train_cli;
mod video_cli;
mod view_browser;
mod view_cli;
