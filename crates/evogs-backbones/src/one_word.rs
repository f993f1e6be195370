//! Settings spelled by one word (on the command line and in `config.json`): [`OneWord`] and the
//! one message for a word that spells no value, [`unknown_message`] (both defined in
//! [`splat_core::one_word`], re-exported here), and [`unknown`], that message as a
//! [`BackboneError`]. The trainer's settings (method, backbone, preset, …) use them as the
//! backbones' settings do.

pub use splat_core::one_word::{OneWord, unknown_message};

use crate::error::BackboneError;

/// [`unknown_message`] as the error of the setting [`OneWord::FIELD`].
pub fn unknown<T: OneWord>(value: &str) -> BackboneError {
    BackboneError::config(T::FIELD, unknown_message::<T>(value))
}
