//! Keyset pagination: the `{items, next}` envelope.
//!
//! The `next` cursor is the natural key of the page's last item — a sensor id
//! for sensors, a calibration id for a sensor's history — and the next page
//! holds the items strictly after it in the list's order. Keyset pages stay
//! correct while calibrations are added, unlike offsets, and a cursor is
//! readable and can be typed by hand.

use serde::Serialize;

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
            items.last().map(key)
        } else {
            None
        };
        Page { items, next }
    }
}
