//! Strings from clients: character classes and lengths, and how much of them
//! an answer or a log line may repeat.

use super::auth;
use super::limits::MAX_ECHO_CHARS;

/// What characters a string may hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Chars {
    /// An identifier: ASCII letters, digits and `. _ : -`, starting with a
    /// letter or digit (safe in URL paths and logs).
    Identifier,
    /// One line of text: no control characters.
    Line,
    /// Free text: no control characters but tab, line feed and carriage return.
    Text,
}

/// Checks a string against a length bound (in characters) and a class.
pub fn check_str(s: &str, max: usize, chars: Chars) -> Result<(), String> {
    let n = s.chars().count();
    if n == 0 {
        return Err("must not be empty".into());
    }
    if n > max {
        return Err(format!("must be at most {max} characters, not {n}"));
    }
    match chars {
        Chars::Identifier => {
            let ok_char = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | ':' | '-');
            if !s.starts_with(|c: char| c.is_ascii_alphanumeric()) || !s.chars().all(ok_char) {
                return Err(
                    "must start with a letter or digit and hold only ASCII letters, digits and . _ : -"
                        .into(),
                );
            }
        }
        Chars::Line => {
            if s.chars().any(char::is_control) {
                return Err("must not contain control characters".into());
            }
        }
        Chars::Text => {
            if s.chars()
                .any(|c| c.is_control() && !matches!(c, '\t' | '\n' | '\r'))
            {
                return Err(
                    "must not contain control characters other than tab and newline".into(),
                );
            }
        }
    }
    Ok(())
}

/// Client input as an answer or a log line may repeat it: any pasted token's
/// secret redacted ([`auth::redact`]), control characters replaced, and at
/// most [`MAX_ECHO_CHARS`] characters, the rest marked `…`.
pub fn echo(s: &str) -> String {
    let redacted = auth::redact(s);
    let mut out: String = redacted
        .chars()
        .take(MAX_ECHO_CHARS)
        .map(|c| if c.is_control() { '\u{fffd}' } else { c })
        .collect();
    if redacted.chars().nth(MAX_ECHO_CHARS).is_some() {
        out.push('…');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn string_classes() {
        assert!(check_str("ACC-0042", 64, Chars::Identifier).is_ok());
        assert!(check_str("-x", 64, Chars::Identifier).is_err());
        assert!(check_str("a/b", 64, Chars::Identifier).is_err());
        assert!(check_str("mA\u{7}", 64, Chars::Line).is_err());
        assert!(check_str("line one\nline two", 64, Chars::Text).is_ok());
        assert!(check_str("", 64, Chars::Text).is_err());
        assert!(check_str("ééé", 2, Chars::Line).is_err());
        // The bound counts characters, not bytes, and admits exactly `max`.
        assert!(check_str("éé", 2, Chars::Line).is_ok());
    }

    #[test]
    fn echo_truncates_and_neutralises() {
        assert_eq!(echo("short"), "short");
        let long = "x".repeat(60_000);
        let e = echo(&long);
        assert_eq!(e.chars().count(), MAX_ECHO_CHARS + 1);
        assert!(e.ends_with('…'));
        assert_eq!(echo("a\nb"), "a\u{fffd}b");
    }
}
