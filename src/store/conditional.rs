//! Conditional writes of definitions (standards, customers, items, sensor
//! types): each write reads the record it replaces and writes the new one in
//! one transaction — on PostgreSQL under a transaction-scoped advisory lock
//! on the record, so that two replicas' writes of one record apply one after
//! the other and a merge (a standard's earlier certificates) never loses
//! what the other wrote — and honours the client's precondition
//! (`If-Match`, `If-None-Match`: RFC 9110 §13.1) against the record's entity
//! tag.
//!
//! A record's entity tag is the first 128 bits of the SHA-256 of its stored
//! JSON definition, quoted: `"3f0c…"` (strong: any change of the record
//! changes it).

use serde::Serialize;
use sha2::{Digest, Sha256};

/// What a write requires of the record it replaces.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Precondition {
    /// Nothing: create or replace (no precondition header).
    #[default]
    Any,
    /// The record exists with one of these entity tags (`If-Match`).
    Matches(Vec<String>),
    /// The record exists (`If-Match: *`).
    Exists,
    /// The record does not exist (`If-None-Match: *`).
    Absent,
}

impl Precondition {
    /// Whether it holds for a record whose entity tag is `current` (`None`:
    /// no record).
    pub fn holds(&self, current: Option<&str>) -> bool {
        match self {
            Precondition::Any => true,
            Precondition::Matches(tags) => current.is_some_and(|c| tags.iter().any(|t| t == c)),
            Precondition::Exists => current.is_some(),
            Precondition::Absent => current.is_none(),
        }
    }
}

/// What a conditional write came to.
#[derive(Clone, Debug, PartialEq)]
pub enum Put<T> {
    /// Written: whether it was created, the record as stored, its entity
    /// tag.
    Written {
        /// Whether the record is new.
        created: bool,
        /// The record as stored (for a standard, merged with the one it
        /// replaced).
        record: T,
        /// Its entity tag.
        etag: String,
    },
    /// The precondition failed; nothing was written. The current record's
    /// entity tag, if there is one.
    Failed {
        /// The current entity tag.
        current: Option<String>,
    },
}

impl<T> Put<T> {
    /// Whether the write created the record (false when it replaced one or
    /// failed).
    pub fn created(&self) -> bool {
        matches!(self, Put::Written { created: true, .. })
    }

    /// The record written, if it was.
    pub fn written(self) -> Option<T> {
        match self {
            Put::Written { record, .. } => Some(record),
            Put::Failed { .. } => None,
        }
    }
}

/// A definition that knows when it was written.
pub trait Updated {
    /// When it was last written.
    fn updated_at(&self) -> crate::domain::timestamp::Timestamp;
}

macro_rules! updated {
    ($($t:ty),*) => {$(
        impl Updated for $t {
            fn updated_at(&self) -> crate::domain::timestamp::Timestamp {
                self.updated_at
            }
        }
    )*};
}

updated!(
    crate::domain::standards::Standard,
    crate::domain::customers::Customer,
    crate::domain::customers::Item,
    crate::domain::sensor_types::SensorType
);

/// The entity tag of a stored definition's JSON text.
pub fn etag_of_text(definition: &str) -> String {
    let digest = Sha256::digest(definition.as_bytes());
    format!("\"{}\"", hex::encode(&digest[..16]))
}

/// The entity tag of a definition as it is stored (its JSON text,
/// `serde_json`'s, as the engines write it).
pub fn etag<T: Serialize>(record: &T) -> String {
    etag_of_text(&serde_json::to_string(record).unwrap_or_default())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preconditions_judge_the_current_tag() {
        let tag = etag(&serde_json::json!({"a": 1}));
        assert_eq!(tag.len(), 34);
        assert!(tag.starts_with('"') && tag.ends_with('"'));
        assert_ne!(tag, etag(&serde_json::json!({"a": 2})));
        for (pre, none, some) in [
            (Precondition::Any, true, true),
            (Precondition::Exists, false, true),
            (Precondition::Absent, true, false),
            (Precondition::Matches(vec![tag.clone()]), false, true),
            (Precondition::Matches(vec!["\"x\"".into()]), false, false),
        ] {
            assert_eq!(pre.holds(None), none, "{pre:?}");
            assert_eq!(pre.holds(Some(&tag)), some, "{pre:?}");
        }
    }
}
