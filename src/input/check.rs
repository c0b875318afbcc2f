//! A small validator over parsed JSON that collects every problem it finds,
//! each with the RFC 6901 pointer of the offending value.

use std::fmt;

use serde::Serialize;
use serde_json::{Map, Value};

/// One problem with one part of the input.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FieldError {
    /// JSON pointer to the offending value (`/runs/2/readings/1`).
    pub pointer: String,
    /// What is wrong, in words.
    pub detail: String,
}

/// A JSON pointer under construction.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Ptr(String);

impl Ptr {
    /// The whole document (`""`).
    pub fn root() -> Self {
        Ptr(String::new())
    }

    /// The member `key` of this object, escaped per RFC 6901.
    pub fn key(&self, key: &str) -> Ptr {
        Ptr(format!(
            "{}/{}",
            self.0,
            key.replace('~', "~0").replace('/', "~1")
        ))
    }

    /// The element `index` of this array.
    pub fn index(&self, index: usize) -> Ptr {
        Ptr(format!("{}/{index}", self.0))
    }
}

impl fmt::Display for Ptr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

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

/// Accumulates field errors while walking a value.
#[derive(Debug, Default)]
pub struct Checker {
    errors: Vec<FieldError>,
}

impl Checker {
    /// A checker with no errors yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records a problem at `ptr`.
    pub fn error(&mut self, ptr: &Ptr, detail: impl Into<String>) {
        self.errors.push(FieldError {
            pointer: ptr.to_string(),
            detail: detail.into(),
        });
    }

    /// Whether nothing has been found wrong so far.
    pub fn is_clean(&self) -> bool {
        self.errors.is_empty()
    }

    /// The errors found, if any.
    pub fn finish(self) -> Result<(), Vec<FieldError>> {
        if self.errors.is_empty() {
            Ok(())
        } else {
            Err(self.errors)
        }
    }

    /// `v` as an object whose members are all among `fields`; unknown members
    /// are reported one by one.
    pub fn object<'v>(
        &mut self,
        v: &'v Value,
        ptr: &Ptr,
        fields: &[&str],
    ) -> Option<&'v Map<String, Value>> {
        let Value::Object(map) = v else {
            self.error(ptr, format!("must be an object, not {}", kind(v)));
            return None;
        };
        for key in map.keys().filter(|k| !fields.contains(&k.as_str())) {
            self.error(
                &ptr.key(key),
                format!(
                    "unknown field `{key}`; expected one of: {}",
                    fields.join(", ")
                ),
            );
        }
        Some(map)
    }

    /// A required member: reports its absence (or `null`).
    pub fn required<'v>(
        &mut self,
        map: &'v Map<String, Value>,
        ptr: &Ptr,
        key: &str,
    ) -> Option<&'v Value> {
        let v = optional(map, key);
        if v.is_none() {
            self.error(&ptr.key(key), "is required");
        }
        v
    }

    /// `v` as an array of `min..=max` elements.
    pub fn array<'v>(
        &mut self,
        v: &'v Value,
        ptr: &Ptr,
        min: usize,
        max: usize,
    ) -> Option<&'v [Value]> {
        let Value::Array(items) = v else {
            self.error(ptr, format!("must be an array, not {}", kind(v)));
            return None;
        };
        if items.len() < min {
            let what = if items.is_empty() {
                "must not be empty".to_owned()
            } else {
                format!("must hold at least {min} elements, not {}", items.len())
            };
            self.error(ptr, what);
            return None;
        }
        if items.len() > max {
            self.error(
                ptr,
                format!("must hold at most {max} elements, not {}", items.len()),
            );
            return None;
        }
        Some(items)
    }

    /// `v` as a finite number with `|v| ≤ bound`.
    pub fn number(&mut self, v: &Value, ptr: &Ptr, bound: f64) -> Option<f64> {
        let Some(x) = v.as_f64() else {
            self.error(ptr, format!("must be a number, not {}", kind(v)));
            return None;
        };
        if !x.is_finite() || x.abs() > bound {
            self.error(
                ptr,
                format!("must be a finite number of magnitude at most {bound:e}"),
            );
            return None;
        }
        Some(x)
    }

    /// `v` as an integer in `min..=max`.
    pub fn integer(&mut self, v: &Value, ptr: &Ptr, min: u64, max: u64) -> Option<u64> {
        match v.as_u64() {
            Some(n) if (min..=max).contains(&n) => Some(n),
            _ if v.is_number() => {
                self.error(ptr, format!("must be an integer from {min} to {max}"));
                None
            }
            _ => {
                self.error(ptr, format!("must be an integer, not {}", kind(v)));
                None
            }
        }
    }

    /// `v` as a string of `1..=max` characters of the given class.
    pub fn string(&mut self, v: &Value, ptr: &Ptr, max: usize, chars: Chars) -> Option<String> {
        let Some(s) = v.as_str() else {
            self.error(ptr, format!("must be a string, not {}", kind(v)));
            return None;
        };
        match check_str(s, max, chars) {
            Ok(()) => Some(s.to_owned()),
            Err(why) => {
                self.error(ptr, why);
                None
            }
        }
    }
}

/// Checks a string against a length bound and a character class.
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

/// A member that is present and not `null`.
pub fn optional<'v>(map: &'v Map<String, Value>, key: &str) -> Option<&'v Value> {
    map.get(key).filter(|v| !v.is_null())
}

/// The JSON type of `v`, for messages.
pub fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn pointers_escape_keys() {
        assert_eq!(
            Ptr::root().key("a/b").key("m~n").index(3).to_string(),
            "/a~1b/m~0n/3"
        );
    }

    #[test]
    fn collects_every_problem() {
        let v = json!({"sensor": "x", "n": 1.5, "s": "bad id", "list": []});
        let mut c = Checker::new();
        let root = Ptr::root();
        let m = c.object(&v, &root, &["n", "s", "list"]).unwrap();
        c.integer(&m["n"], &root.key("n"), 1, 10);
        c.string(&m["s"], &root.key("s"), 64, Chars::Identifier);
        c.array(&m["list"], &root.key("list"), 1, 5);
        let errors = c.finish().unwrap_err();
        let pointers: Vec<&str> = errors.iter().map(|e| e.pointer.as_str()).collect();
        assert_eq!(pointers, ["/sensor", "/n", "/s", "/list"]);
        assert!(errors[0].detail.contains("unknown field `sensor`"));
    }

    #[test]
    fn string_classes() {
        assert!(check_str("ACC-0042", 64, Chars::Identifier).is_ok());
        assert!(check_str("-x", 64, Chars::Identifier).is_err());
        assert!(check_str("a/b", 64, Chars::Identifier).is_err());
        assert!(check_str("mA\u{7}", 64, Chars::Line).is_err());
        assert!(check_str("line one\nline two", 64, Chars::Text).is_ok());
        assert!(check_str("", 64, Chars::Text).is_err());
        assert!(check_str("ééé", 2, Chars::Line).is_err());
    }
}
