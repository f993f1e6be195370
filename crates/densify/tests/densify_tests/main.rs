//! densify's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p densify --test densify_tests <module>::`.

mod common;
mod properties;
mod rules;
mod summary;
