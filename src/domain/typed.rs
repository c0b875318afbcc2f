//! Small request bodies read straight into `#[serde(deny_unknown_fields)]`
//! structs, with the JSON pointer of the first value that does not fit.
//!
//! Syntax errors (not JSON at all) are [`BodyError::Syntax`], answered 400;
//! well-formed JSON of the wrong shape — an unknown or repeated member, a
//! missing one, a value of the wrong type — is [`BodyError::Invalid`],
//! answered 422 with the pointer. Range and cross-field checks then run on
//! the typed value and may add more problems.

use serde::de::DeserializeOwned;
use serde_path_to_error::Segment;

use super::field::{Invalid, Loc};
use super::text::echo;

/// Why a body could not be read as its type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BodyError {
    /// Not JSON (or not UTF-8): the parser's complaint, without input.
    Syntax(String),
    /// JSON of the wrong shape.
    Invalid(Invalid),
}

impl From<Invalid> for BodyError {
    fn from(e: Invalid) -> Self {
        BodyError::Invalid(e)
    }
}

/// The parser's message without serde_json's " at line L column C" suffix.
pub fn message(e: &serde_json::Error) -> String {
    let text = e.to_string();
    match text.rfind(" at line ") {
        Some(k) => text[..k].to_owned(),
        None => text,
    }
}

/// The `name` in a message such as ``unknown field `name`, expected …``.
fn quoted_member<'m>(message: &'m str, lead: &str) -> Option<&'m str> {
    let rest = message.strip_prefix(lead)?;
    rest.split_once('`').map(|(name, _)| name)
}

/// Reads `bytes` as one JSON value of type `T`.
pub fn from_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, BodyError> {
    // Every body is a JSON object; serde would also read a struct from an
    // array of its fields in order (and one of optional fields from `[]`).
    if bytes.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'[') {
        return Err(BodyError::Invalid(Invalid::one(
            Loc::Root,
            "must be a JSON object, not an array",
        )));
    }
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let result = serde_path_to_error::deserialize::<_, T>(&mut de);
    match result {
        Ok(v) => {
            de.end().map_err(|e| BodyError::Syntax(e.to_string()))?;
            Ok(v)
        }
        Err(e) => {
            let inner = e.inner();
            // serde_json reports an array longer than a fixed-size one
            // (three outputs) as "trailing characters", a syntax error; in
            // a body that is valid JSON it is the content's fault.
            let too_long = !inner.is_data()
                && inner.to_string().starts_with("trailing characters")
                && serde_json::from_slice::<serde::de::IgnoredAny>(bytes).is_ok();
            if !inner.is_data() && !too_long {
                // Where the syntax breaks is worth saying.
                return Err(BodyError::Syntax(inner.to_string()));
            }
            let msg = if too_long {
                "has more elements than allowed".to_owned()
            } else {
                message(inner)
            };
            let segments: Vec<String> = e
                .path()
                .iter()
                .filter_map(|s| match s {
                    Segment::Seq { index } => Some(index.to_string()),
                    Segment::Map { key } => Some(key.clone()),
                    Segment::Enum { .. } | Segment::Unknown => None,
                })
                .collect();
            let mut pointer = String::new();
            let root = Loc::Root;
            for s in &segments {
                pointer.push_str(&root.key(s).to_string());
            }
            // The member a message names, unless the path already ends there.
            let last = segments.last().cloned();
            let mut loc_text = |seg: &str| {
                if last.as_deref() != Some(seg) {
                    pointer.push_str(&root.key(seg).to_string());
                }
            };
            let detail = if let Some(name) = quoted_member(&msg, "unknown field `") {
                loc_text(name);
                let expected = msg.split_once(", expected ").map_or("", |(_, e)| e);
                format!("unknown field `{}`; expected {expected}", echo(name))
            } else if let Some(name) = quoted_member(&msg, "missing field `") {
                loc_text(name);
                "is required".to_owned()
            } else if let Some(name) = quoted_member(&msg, "duplicate field `")
                .or_else(|| quoted_member(&msg, "duplicate term `"))
            {
                loc_text(name);
                format!("duplicate key `{}`: given more than once", echo(name))
            } else if let Some(name) = quoted_member(&msg, "unknown term `") {
                loc_text(name);
                crate::domain::submission::json::unknown_term(name)
            } else {
                msg
            };
            Err(BodyError::Invalid(Invalid::one(pointer, detail)))
        }
    }
}

#[cfg(test)]
mod tests {
    use serde::Deserialize;

    use super::*;

    #[derive(Debug, Deserialize, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Body {
        outputs: Vec<f64>,
        #[serde(default)]
        label: Option<String>,
    }

    fn invalid(bytes: &str) -> (String, String) {
        match from_json::<Body>(bytes.as_bytes()) {
            Err(BodyError::Invalid(i)) => (i.errors[0].pointer.clone(), i.errors[0].detail.clone()),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_fixed_size_array_too_long_is_the_contents_fault() {
        #[derive(Debug, serde::Deserialize)]
        #[allow(dead_code)]
        struct Triples {
            t: Vec<[f64; 3]>,
        }
        match from_json::<Triples>(br#"{"t": [[1, 2, 3], [1, 2, 3, 4]]}"#) {
            Err(BodyError::Invalid(i)) => {
                assert_eq!(i.errors[0].pointer, "/t/1");
                assert_eq!(i.errors[0].detail, "has more elements than allowed");
            }
            other => panic!("{other:?}"),
        }
        // Trailing characters after the document are still a syntax error.
        assert!(matches!(
            from_json::<Triples>(br#"{"t": []} x"#),
            Err(BodyError::Syntax(_))
        ));
    }

    #[test]
    fn an_array_is_not_an_object() {
        #[derive(Debug, serde::Deserialize)]
        #[allow(dead_code)]
        struct AllOptional {
            #[serde(default)]
            a: Option<String>,
        }
        for body in ["[]", " \n[null]"] {
            match from_json::<AllOptional>(body.as_bytes()) {
                Err(BodyError::Invalid(i)) => {
                    assert_eq!(i.errors[0].pointer, "");
                    assert!(i.errors[0].detail.contains("JSON object"));
                }
                other => panic!("{body}: {other:?}"),
            }
        }
        assert!(from_json::<AllOptional>(b"{}").is_ok());
    }

    #[test]
    fn pointers_name_the_value_that_does_not_fit() {
        assert_eq!(
            from_json::<Body>(br#"{"outputs": [1, 2.5]}"#),
            Ok(Body {
                outputs: vec![1.0, 2.5],
                label: None
            })
        );
        let (p, d) = invalid(r#"{"outputs": [1, "x"]}"#);
        assert_eq!(p, "/outputs/1");
        assert!(d.starts_with("invalid type: string"), "{d}");
        assert!(!d.contains("line"), "{d}");
        let (p, d) = invalid(r#"{"outputs": [], "extra": 1}"#);
        assert_eq!(
            (p.as_str(), d.starts_with("unknown field `extra`")),
            ("/extra", true)
        );
        assert_eq!(invalid(r#"{}"#), ("/outputs".into(), "is required".into()));
        let (p, _) = invalid(r#"{"outputs": [], "outputs": []}"#);
        assert_eq!(p, "/outputs");
        assert!(matches!(from_json::<Body>(b"{"), Err(BodyError::Syntax(_))));
        assert!(matches!(
            from_json::<Body>(br#"{"outputs": []} x"#),
            Err(BodyError::Syntax(_))
        ));
    }

    #[test]
    fn a_huge_unknown_key_is_not_echoed_in_full() {
        let key = "k".repeat(60_000);
        let (p, d) = invalid(&format!(r#"{{"outputs": [], "{key}": 1}}"#));
        assert!(p.len() < 100 && d.len() < 400, "{} {}", p.len(), d.len());
    }
}
