//! Settings spelled by one word (on the command line and in files): the trait that names the
//! setting a parse error is about, and the one message for a word that spells no value,
//! "unknown method `x`; expected baseline or evogs".
//!
//! Every crate's one-word enums (`strum`'s `EnumString` with a `parse_err_fn`: the dataset
//! split and the time rule of `evogs-io`, the rasterizer backend, the backbones' and the
//! trainer's settings, the matcher of `evogs-prepare`, the export format of `evogs-eval`)
//! implement [`OneWord`] and build their parse error from [`unknown_message`], each crate
//! wrapping the message in its own error type.

use strum::VariantNames;

/// A setting spelled by one word (on the command line and in files): the field its parse
/// errors name and how the message calls a value.
pub trait OneWord: VariantNames {
    /// The setting's field in files (and its `--` flag).
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

#[cfg(test)]
mod tests {
    use super::{OneWord, unknown_message};

    macro_rules! word {
        ($name:ident, $noun:literal, $one_of:literal, [$($v:literal),*]) => {
            struct $name;
            impl strum::VariantNames for $name {
                const VARIANTS: &'static [&'static str] = &[$($v),*];
            }
            impl OneWord for $name {
                const FIELD: &'static str = "field";
                const NOUN: &'static str = $noun;
                const ONE_OF: bool = $one_of;
            }
        };
    }

    word!(None0, "a", false, []);
    word!(One, "a", false, ["c"]);
    word!(Two, "a", false, ["c", "d"]);
    word!(Three, "time rule", false, ["order", "name", "none"]);
    word!(
        OneOf,
        "policy",
        true,
        ["standard", "trigger", "trigger+deform"]
    );

    #[test]
    fn messages_list_every_spelling() {
        assert_eq!(unknown_message::<None0>("b"), "unknown a `b`; expected ");
        assert_eq!(unknown_message::<One>("b"), "unknown a `b`; expected c");
        assert_eq!(
            unknown_message::<Two>("b"),
            "unknown a `b`; expected c or d"
        );
        assert_eq!(
            unknown_message::<Three>("Order"),
            "unknown time rule `Order`; expected order, name or none"
        );
        assert_eq!(
            unknown_message::<OneOf>("x"),
            "unknown policy `x`; expected one of standard, trigger, trigger+deform"
        );
    }
}
