//! evogs-io's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p evogs-io --test evogs_io_tests <module>::`.

mod cameras;
mod common;
mod compressed_ply;
mod dataset_errors;
mod datasets;
mod dnerf;
mod images;
mod ply_formats;
mod ply_fuzz;
