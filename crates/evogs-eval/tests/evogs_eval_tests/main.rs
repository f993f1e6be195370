//! evogs-eval's integration tests, as one binary (a module per file). One module alone:
//! `cargo test --workspace --locked --test evogs_eval_tests <module>::`.

mod common;
mod eval_non_finite;
mod eval_table;
