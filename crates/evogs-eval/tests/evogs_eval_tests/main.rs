//! evogs-eval's integration tests, as one binary (a module per file). One module alone:
//! `cargo test --workspace --locked --test evogs_eval_tests <module>::`.

// evogs-train's tiny scene, shared with its tests and evogs-cli's (included by path).
#[path = "../../../evogs-train/tests/common/mod.rs"]
mod common;
mod eval_non_finite;
mod eval_table;
