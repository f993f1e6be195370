//! `evo-state`: the EvoGS deformation evolution state machine (SPEC §4), usable with any renderer.
//!
//! (Work in progress; the full API walk-through follows.)

pub mod buffer;
pub mod config;
pub mod error;
pub mod frames;
pub mod gain;
pub mod persist;
pub mod rows;
pub mod state;
pub mod step;

pub use buffer::StateBuffer;
pub use config::{Component, EvoConfig, Gain, HistoryMode, Layout, Storage};
pub use error::EvoError;
pub use frames::{Frames, History};
pub use gain::GainNet;
pub use rows::{NewRows, RowPlan};
pub use state::{EvoState, ObservationSource};
pub use step::{Backward, Gains, Losses, Stats, Step};
