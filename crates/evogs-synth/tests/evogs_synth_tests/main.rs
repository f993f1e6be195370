//! evogs-synth's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p evogs-synth --test evogs_synth_tests <module>::`.

mod dnerf_files;
mod synth;
