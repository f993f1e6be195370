//! The one line an error is printed as. Messages quote text from the user's files (a PLY
//! header, a camera's JSON, a dataset's names): line breaks become spaces, and every other
//! control character is escaped (`\u{1b}`), so that a file cannot clear the terminal, set its
//! title or split the line (the viewer filters such bytes the same way).

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

#[cfg(test)]
mod tests {
    use super::one_line;

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
