//! Field-level problems: what is wrong with which part of a request body,
//! named by an RFC 6901 JSON pointer (`/runs/2/readings/1`).
//!
//! Validation reports every fault it finds, so a client learns all that is
//! wrong in one answer — but never more than [`MAX_LISTED_ERRORS`] of them
//! (the rest are counted), and never more than a bounded excerpt of the
//! client's own input, so that a hostile body cannot make the answer grow
//! with the square of its size.

use std::fmt;

use serde::Serialize;

use super::limits::MAX_LISTED_ERRORS;
use super::text::echo;

/// Longest `detail` of one field error, in characters.
const MAX_DETAIL_CHARS: usize = 400;

/// One problem with one part of the input.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub struct FieldError {
    /// RFC 6901 JSON pointer to the offending value (`""`: the whole body).
    pub pointer: String,
    /// What is wrong, in words.
    pub detail: String,
}

/// A location in a JSON document, built without allocating: each level
/// borrows its parent, and the pointer text is made only when a problem is
/// reported.
#[derive(Clone, Copy, Debug)]
pub enum Loc<'p> {
    /// The whole document.
    Root,
    /// Member `key` of the object at the parent location.
    Key(&'p Loc<'p>, &'p str),
    /// Element `index` of the array at the parent location.
    Index(&'p Loc<'p>, usize),
}

impl Loc<'_> {
    /// The member `key` of this object.
    pub fn key<'a>(&'a self, key: &'a str) -> Loc<'a> {
        Loc::Key(self, key)
    }

    /// The element `index` of this array.
    pub fn index(&self, index: usize) -> Loc<'_> {
        Loc::Index(self, index)
    }
}

impl fmt::Display for Loc<'_> {
    /// The pointer text, keys escaped per RFC 6901 (`~` → `~0`, `/` → `~1`)
    /// and cut to what an answer may echo.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Loc::Root => Ok(()),
            Loc::Key(parent, key) => {
                write!(f, "{parent}/")?;
                f.write_str(&echo(key).replace('~', "~0").replace('/', "~1"))
            }
            Loc::Index(parent, index) => write!(f, "{parent}/{index}"),
        }
    }
}

/// A request body (or part of one) that is well-formed but wrong: the
/// listed problems, and how many more were found but not listed.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Invalid {
    /// The first [`MAX_LISTED_ERRORS`] problems, in the order found.
    pub errors: Vec<FieldError>,
    /// Problems found beyond those listed.
    pub omitted: usize,
}

impl Invalid {
    /// One problem at `pointer`.
    pub fn one(pointer: impl fmt::Display, detail: impl Into<String>) -> Self {
        let mut e = Errors::default();
        e.add(pointer, detail);
        e.into_invalid()
    }

    /// Every problem found, listed or not.
    pub fn count(&self) -> usize {
        self.errors.len() + self.omitted
    }
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.errors.as_slice() {
            [one] if self.omitted == 0 && one.pointer.is_empty() => f.write_str(&one.detail),
            [one] if self.omitted == 0 => write!(f, "{}: {}", one.pointer, one.detail),
            _ if self.omitted > 0 => write!(
                f,
                "{} problems in the request body (the first {} are listed)",
                self.count(),
                self.errors.len()
            ),
            many => write!(f, "{} problems in the request body", many.len()),
        }
    }
}

impl std::error::Error for Invalid {}

/// Collects field errors, keeping the first [`MAX_LISTED_ERRORS`].
#[derive(Debug, Default)]
pub struct Errors {
    listed: Vec<FieldError>,
    omitted: usize,
}

impl Errors {
    /// Records a problem at `pointer`.
    pub fn add(&mut self, pointer: impl fmt::Display, detail: impl Into<String>) {
        if self.listed.len() >= MAX_LISTED_ERRORS {
            self.omitted += 1;
            return;
        }
        let mut detail = detail.into();
        if let Some((cut, _)) = detail.char_indices().nth(MAX_DETAIL_CHARS) {
            detail.truncate(cut);
            detail.push('…');
        }
        self.listed.push(FieldError {
            pointer: pointer.to_string(),
            detail,
        });
    }

    /// Whether nothing has been found wrong so far.
    pub fn is_empty(&self) -> bool {
        self.listed.is_empty()
    }

    /// Everything found, as the error of a validation.
    pub fn into_invalid(self) -> Invalid {
        Invalid {
            errors: self.listed,
            omitted: self.omitted,
        }
    }

    /// `Ok(value)` when nothing was found wrong, else the problems.
    pub fn finish<T>(self, value: impl FnOnce() -> T) -> Result<T, Invalid> {
        if self.is_empty() {
            Ok(value())
        } else {
            Err(self.into_invalid())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pointers_escape_and_bound_keys() {
        let root = Loc::Root;
        let a = root.key("a/b");
        let m = a.key("m~n");
        assert_eq!(m.index(3).to_string(), "/a~1b/m~0n/3");
        let long = "k".repeat(10_000);
        let p = root.key(&long).to_string();
        assert!(p.chars().count() < 100, "{}", p.len());
    }

    #[test]
    fn the_list_is_capped_and_the_rest_counted() {
        let mut e = Errors::default();
        for k in 0..1000 {
            e.add(Loc::Root.index(k), "x".repeat(10_000));
        }
        let inv = e.into_invalid();
        assert_eq!(inv.errors.len(), MAX_LISTED_ERRORS);
        assert_eq!(inv.omitted, 1000 - MAX_LISTED_ERRORS);
        assert!(inv.errors[0].detail.chars().count() <= MAX_DETAIL_CHARS + 1);
        assert_eq!(
            inv.to_string(),
            "1000 problems in the request body (the first 100 are listed)"
        );
        assert_eq!(Invalid::one("/a", "is wrong").to_string(), "/a: is wrong");
    }

    /// One listed problem with more omitted is summarised as a count, not
    /// shown as if it were the only one.
    #[test]
    fn one_listed_problem_with_more_omitted_is_counted() {
        let inv = Invalid {
            errors: vec![FieldError {
                pointer: "/a".into(),
                detail: "is wrong".into(),
            }],
            omitted: 2,
        };
        assert_eq!(
            inv.to_string(),
            "3 problems in the request body (the first 1 are listed)"
        );
    }

    /// Several problems, every one listed: a count, without "the first".
    #[test]
    fn several_problems_all_listed_are_counted_alone() {
        let mut e = Errors::default();
        e.add("/a", "is wrong");
        e.add("/b", "is wrong too");
        assert_eq!(
            e.into_invalid().to_string(),
            "2 problems in the request body"
        );
    }

    /// A problem with the whole body has no pointer to print before it.
    #[test]
    fn a_problem_at_the_root_is_its_detail_alone() {
        assert_eq!(
            Invalid::one(Loc::Root, "must be a JSON object").to_string(),
            "must be a JSON object"
        );
    }
}
