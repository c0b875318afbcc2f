//! Turning untrusted request bodies into checked values.
//!
//! [`strict`] parses JSON refusing duplicate keys and deep nesting; [`check`]
//! walks the parsed value collecting every problem as a `{pointer, detail}`
//! pair (RFC 6901 JSON pointers), so a client learns all that is wrong with a
//! submission in one answer; [`csv`] turns the documented CSV layout into the
//! same JSON form.

pub mod check;
pub mod csv;
pub mod strict;

pub use check::{Checker, FieldError, Ptr};
