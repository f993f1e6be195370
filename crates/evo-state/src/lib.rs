//! `evo-state`: the EvoGS deformation evolution state machine (SPEC §4), usable with any renderer.
//!
//! (Work in progress; the full API walk-through follows.)

pub mod rows;
