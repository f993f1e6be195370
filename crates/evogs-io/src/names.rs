//! The error text of the one-word enums' `from_str` ([`crate::dnerf::Split`],
//! [`crate::frame_time::TimeFrom`]): one wording for all of them.

/// `unknown <what> `<value>`; expected a, b or c`.
pub(crate) fn unknown(what: &str, value: &str, names: &[&str]) -> String {
    let expected = match names.split_last() {
        Some((last, [])) => (*last).to_string(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    };
    format!("unknown {what} `{value}`; expected {expected}")
}

#[cfg(test)]
mod tests {
    use super::unknown;
    use crate::dnerf::Split;
    use crate::frame_time::TimeFrom;

    #[test]
    fn messages_list_every_spelling() {
        assert_eq!(
            "x".parse::<Split>().unwrap_err(),
            "unknown split `x`; expected train, test or val"
        );
        assert_eq!(
            "Order".parse::<TimeFrom>().unwrap_err(),
            "unknown time rule `Order`; expected order, name or none"
        );
        assert_eq!(unknown("a", "b", &["c"]), "unknown a `b`; expected c");
        assert_eq!(
            unknown("a", "b", &["c", "d"]),
            "unknown a `b`; expected c or d"
        );
    }

    #[test]
    fn spellings_round_trip() {
        for split in Split::ALL {
            assert_eq!(split.to_string().parse::<Split>(), Ok(split));
            assert_eq!(split.name(), split.to_string());
        }
        for rule in TimeFrom::ALL {
            assert_eq!(rule.to_string().parse::<TimeFrom>(), Ok(rule));
            assert_eq!(rule.name(), rule.to_string());
        }
    }
}
