//! Settings spelled by one word (on the command line and in `config.json`): the trait that names
//! the field a parse error is about, and the one message for a word that spells no value. The
//! trainer's settings (method, backbone, preset, …) use it as the backbones' settings do.

use strum::VariantNames;

use crate::error::BackboneError;

/// A setting spelled by one word (on the command line and in `config.json`): the field its
/// parse errors name.
pub trait OneWord: VariantNames {
    /// The `config.json` field (and `--` flag) of the setting.
    const FIELD: &'static str;
    /// What a value is called in the error message.
    const NOUN: &'static str = Self::FIELD;
    /// The spellings as "one of a, b, c" rather than "a, b or c" (kept as the messages were).
    const ONE_OF: bool = false;
}

/// The message for `value`, which spells no `T`: "unknown method `x`; expected baseline or
/// evogs" (or "expected one of a, b, c" where [`OneWord::ONE_OF`]), the spellings in declaration
/// order.
pub fn unknown_message<T: OneWord>(value: &str) -> String {
    let names = T::VARIANTS;
    let expected = match names.split_last() {
        _ if T::ONE_OF => format!("one of {}", names.join(", ")),
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.join(""),
    };
    format!("unknown {} `{value}`; expected {expected}", T::NOUN)
}

/// [`unknown_message`] as the error of the setting [`OneWord::FIELD`].
pub fn unknown<T: OneWord>(value: &str) -> BackboneError {
    BackboneError::config(T::FIELD, unknown_message::<T>(value))
}
