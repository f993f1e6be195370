//! The one line an error is printed as. Messages quote text from the user's files (a PLY
//! header, a camera's JSON, a dataset's names): line breaks become spaces, and every other
//! control character is escaped (`\u{1b}`), so that a file cannot clear the terminal, set its
//! title or split the line (the viewer filters such bytes the same way); a cause the message
//! already quotes is said once ([`with_causes`]).

/// `text` as one line, trimmed, its line breaks as spaces and other control characters
/// (C0, DEL, C1) escaped.
pub fn one_line(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.trim().chars() {
        match c {
            '\n' | '\r' => out.push(' '),
            c if c.is_control() => out.extend(c.escape_default()),
            c => out.push(c),
        }
    }
    out
}

/// An error and its causes as one text: each cause after a colon, unless the text so far
/// already says it (a library's message often quotes the error it wraps, which is also its
/// source: `network: x.safetensors: No such file` over `x.safetensors: No such file` over
/// `No such file` is said once).
pub fn with_causes(err: &anyhow::Error) -> String {
    let mut text = err.to_string();
    for cause in err.chain().skip(1) {
        let said = cause.to_string();
        if !text.contains(&said) {
            text.push_str(": ");
            text.push_str(&said);
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::{one_line, with_causes};

    #[test]
    fn causes_already_quoted_are_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let quoted = anyhow::Error::new(io).context("x.safetensors: No such file");
        let quoted = quoted.context("network: x.safetensors: No such file");
        assert_eq!(with_causes(&quoted), "network: x.safetensors: No such file");
        // A cause the message does not quote is still said.
        let bare = anyhow::anyhow!("disk full").context("writing run/config.json");
        assert_eq!(with_causes(&bare), "writing run/config.json: disk full");
    }

    #[test]
    fn line_breaks_join_and_control_characters_are_escaped() {
        assert_eq!(one_line("  a\nb\r\nc  "), "a b  c");
        assert_eq!(
            one_line("x.ply: format `\u{1b}[2J\u{7}\u{9b}` unknown"),
            "x.ply: format `\\u{1b}[2J\\u{7}\\u{9b}` unknown"
        );
        assert_eq!(one_line("tab\there é ✓"), "tab\\there é ✓");
        assert!(
            !one_line("\u{1b}]0;title\u{7}")
                .chars()
                .any(char::is_control)
        );
    }
}
