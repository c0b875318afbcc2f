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
            if let Some((n, c)) = first(s, char::is_control) {
                return Err(format!(
                    "must not contain control characters ({} at character {n})",
                    code_point(c)
                ));
            }
        }
        Chars::Text => {
            let control = |c: char| c.is_control() && !matches!(c, '\t' | '\n' | '\r');
            if let Some((n, c)) = first(s, control) {
                return Err(format!(
                    "must not contain control characters other than tab and newline ({} at \
                     character {n})",
                    code_point(c)
                ));
            }
        }
    }
    // XML 1.0 has no place for U+FFFE and U+FFFF, not even as a character
    // reference: text that reaches a Digital Calibration Certificate must
    // not hold them (the other characters XML refuses are controls).
    if let Some((n, c)) = first(s, |c| matches!(c, '\u{fffe}' | '\u{ffff}')) {
        return Err(format!(
            "must not contain {} (character {n}): a noncharacter, which XML 1.0 and so the \
             Digital Calibration Certificate cannot carry",
            code_point(c)
        ));
    }
    Ok(())
}

/// The first character of `s` that is `bad`, with its position (from 1).
fn first(s: &str, bad: impl Fn(char) -> bool) -> Option<(usize, char)> {
    s.chars()
        .enumerate()
        .find(|(_, c)| bad(*c))
        .map(|(i, c)| (i + 1, c))
}

/// A character as Unicode writes it (`U+FFFE`).
fn code_point(c: char) -> String {
    format!("U+{:04X}", u32::from(c))
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
    fn a_refusal_names_the_character_and_where_it_is() {
        assert_eq!(
            check_str("mA\u{7}", 64, Chars::Line).unwrap_err(),
            "must not contain control characters (U+0007 at character 3)"
        );
        for class in [Chars::Line, Chars::Text] {
            for c in ['\u{fffe}', '\u{ffff}'] {
                let why = check_str(&format!("ab{c}"), 64, class).unwrap_err();
                assert!(
                    why.starts_with(&format!(
                        "must not contain U+{:04X} (character 3)",
                        u32::from(c)
                    )),
                    "{why}"
                );
            }
            // Accepted text is what XML carries, kept as sent: the last
            // character before the noncharacters, the private use area,
            // the astral planes and a decomposed accent.
            for ok in ["\u{fffd}", "\u{e000}", "𝔤 = 9.81", "e\u{301}"] {
                assert_eq!(check_str(ok, 64, class), Ok(()), "{ok:?}");
            }
        }
        assert!(check_str("tab\there\r\n", 64, Chars::Text).is_ok());
        assert!(
            check_str("\u{b}", 64, Chars::Text)
                .unwrap_err()
                .contains("U+000B at character 1")
        );
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
