//! The fuzz targets of every file reader of evogs, as plain functions, with their seed corpora.
//!
//! Two users share them, so that what is fuzzed and what CI checks are one source:
//! - the libFuzzer targets in `fuzz/` (nightly, AddressSanitizer, `scripts/fuzz`), each a
//!   one-line wrapper of a function of [`targets`];
//! - this crate's replay test (`tests/replay.rs`, stable, part of the workspace's tests), which
//!   runs every target on its seeds, on every truncation of them, and on every input kept in
//!   `tests/data/<target>/` (the regression inputs: every failure fuzzing ever found).
//!
//! A target checks that its reader returns (`Ok` or a one-line error) without panicking, and
//! that what it returns is self-consistent. Hangs and allocation sizes are libFuzzer's to catch
//! (`-timeout`, `-malloc_limit_mb`).

pub mod scratch;
pub mod seeds;
pub mod targets;

pub use seeds::{seeds_from_env, write_all_seeds};
pub use targets::{TARGETS, Target};
