//! What the binary's integration tests share: running `evogs` and reading its output.

#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `evogs` binary with `args` (help text wrapped at 100 columns, so snapshots are
/// stable) and waits for it.
pub fn evogs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_evogs"))
        .args(args)
        .env("COLUMNS", "100")
        .output()
        .unwrap()
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The process's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
pub mod capture;
pub mod view;
