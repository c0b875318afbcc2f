//! Keyset pagination: opaque cursors and the `{items, next}` envelope.
//!
//! A cursor is the unpadded base64url of the last item's sort key; the next
//! page holds the items strictly after it. Keyset pages stay correct while
//! calibrations are added, unlike offsets.

use base64::Engine as _;
use base64::engine::general_purpose::URL_SAFE_NO_PAD;
use serde::Serialize;

use super::problem::Problem;

/// One page of a list.
#[derive(Debug, Serialize)]
pub struct Page<T> {
    /// The items.
    pub items: Vec<T>,
    /// Cursor for the next page (`after=`), or null on the last page.
    pub next: Option<String>,
}

impl<T> Page<T> {
    /// Builds a page from `limit + 1` fetched items: the extra one only says
    /// whether there is a next page.
    pub fn from_overfetch(mut items: Vec<T>, limit: usize, key: impl Fn(&T) -> String) -> Self {
        let next = if items.len() > limit {
            items.truncate(limit);
            items.last().map(|last| encode(&key(last)))
        } else {
            None
        };
        Page { items, next }
    }
}

/// Encodes a sort key as a cursor.
pub fn encode(key: &str) -> String {
    URL_SAFE_NO_PAD.encode(key)
}

/// Decodes the `after` cursor.
pub fn decode(cursor: &str) -> Result<String, Problem> {
    URL_SAFE_NO_PAD
        .decode(cursor)
        .ok()
        .and_then(|b| String::from_utf8(b).ok())
        .ok_or_else(|| Problem::bad_parameter("after", "is not a cursor returned by this API"))
}
