//! evo-state's integration tests, built as one binary: each module below was its own test
//! binary before (one link instead of one per file, and the harness runs the tests of every
//! module on its threads together). One module alone:
//! `cargo test -p evo-state --test evo_state_tests <module>::`.

mod common;
mod gradients;
mod hard_cases;
mod sequences;
mod state;
