//! The audit trail: every state-changing act, in one hash chain per
//! database (issue 28 item 6).
//!
//! Each entry records its sequence number, time, actor (token id, role,
//! holder), action, object, the change (a JSON document), the previous
//! entry's hash, and its own:
//!
//! ```text
//! hash_n = hex(SHA-256(canonical_n)),   canonical_n names prev = hash_{n-1}
//! hash_0 = "000…0" (64 zeros: the chain's start)
//! ```
//!
//! where `canonical_n` is the UTF-8 text of the JSON object, keys sorted,
//! no white space,
//!
//! ```text
//! {"action":A,"actor":{"holder":H,"role":R,"token_id":T},"at":AT,
//!  "change":C,"object":O,"prev":P,"seq":N}
//! ```
//!
//! with the strings JSON-escaped, `H` `null` for a token without a holder,
//! `AT` the canonical timestamp ([`Timestamp`]) and `C` the change's stored
//! text, verbatim (written once, keys sorted, by [`Event::new`]). Editing an
//! entry changes its hash; editing the hash too breaks the next entry's
//! `prev`; deleting or inserting one breaks the sequence. [`Chain`] checks
//! all three, entry by entry, and names the first that does not hold. What a
//! chain cannot show by itself is its own tail cut off: the head (`seq`,
//! `hash`) that `accelcal audit verify` prints is what to keep elsewhere.

use serde::Serialize;
use serde_json::Value;
use sha2::{Digest, Sha256};
use utoipa::ToSchema;

use super::auth::Principal;
use super::timestamp::Timestamp;

/// The `prev` of the first entry.
pub const GENESIS: &str = "0000000000000000000000000000000000000000000000000000000000000000";

/// Who acted: a token, with its role and holder as they were.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, ToSchema)]
#[schema(as = AuditActor)]
pub struct Actor {
    /// The token's id (`env-admin` for the configured admin token,
    /// `accelcal` for the service itself).
    pub token_id: String,
    /// Its role (`service` for the service itself).
    pub role: String,
    /// The person who held it, if it named one.
    pub holder: Option<String>,
}

impl Actor {
    /// The service itself (its configuration at start).
    pub fn service() -> Actor {
        Actor {
            token_id: "accelcal".into(),
            role: "service".into(),
            holder: None,
        }
    }
}

impl Actor {
    /// Whoever runs `accelcal` at a shell (`accelcal token create`): the
    /// operator, named by the login (`$USER`) when there is one.
    pub fn command_line() -> Actor {
        Actor {
            token_id: "command-line".into(),
            role: "operator".into(),
            holder: std::env::var("USER").ok().filter(|u| !u.is_empty()),
        }
    }
}

impl From<&Principal> for Actor {
    fn from(p: &Principal) -> Actor {
        Actor {
            token_id: p.id.clone(),
            role: p.role.as_str().into(),
            holder: p.holder.clone(),
        }
    }
}

/// An act about to be appended: what the chain adds `seq`, `prev` and
/// `hash` to.
#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    /// When it happened.
    pub at: Timestamp,
    /// Who did it.
    pub actor: Actor,
    /// What was done, e.g. `calibration.approve`.
    pub action: String,
    /// What it was done to, e.g. `calibrations/0193…`.
    pub object: String,
    /// The change, as its canonical JSON text.
    pub change: String,
}

impl Event {
    /// An event whose change is `change` (an object), written with sorted
    /// keys and no white space (serde_json's maps are sorted).
    pub fn new(
        at: Timestamp,
        actor: Actor,
        action: &str,
        object: String,
        change: serde_json::Map<String, Value>,
    ) -> Event {
        Event {
            at,
            actor,
            action: action.into(),
            object,
            change: Value::Object(change).to_string(),
        }
    }
}

/// One entry of the trail, as stored and as `GET /v1/audit` answers it
/// (`change` there parsed).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// Its place in the chain, from 1, without gaps.
    pub seq: i64,
    /// When.
    pub at: Timestamp,
    /// Who.
    pub actor: Actor,
    /// What was done.
    pub action: String,
    /// To what.
    pub object: String,
    /// The change, as stored (canonical JSON text).
    pub change: String,
    /// The previous entry's hash ([`GENESIS`] for the first).
    pub prev: String,
    /// This entry's hash.
    pub hash: String,
}

fn quoted(s: &str) -> String {
    Value::String(s.to_owned()).to_string()
}

impl Entry {
    /// `event` appended after the entry `(seq, hash)`, or first.
    pub fn chain(after: Option<(i64, &str)>, event: Event) -> Entry {
        let (seq, prev) = match after {
            Some((seq, hash)) => (seq + 1, hash.to_owned()),
            None => (1, GENESIS.to_owned()),
        };
        let mut e = Entry {
            seq,
            at: event.at,
            actor: event.actor,
            action: event.action,
            object: event.object,
            change: event.change,
            prev,
            hash: String::new(),
        };
        e.hash = e.digest();
        e
    }

    /// The canonical text the hash is taken over (see the module's doc).
    pub fn canonical(&self) -> String {
        format!(
            "{{\"action\":{},\"actor\":{{\"holder\":{},\"role\":{},\"token_id\":{}}},\"at\":{},\
             \"change\":{},\"object\":{},\"prev\":{},\"seq\":{}}}",
            quoted(&self.action),
            self.actor
                .holder
                .as_deref()
                .map_or_else(|| "null".to_owned(), quoted),
            quoted(&self.actor.role),
            quoted(&self.actor.token_id),
            quoted(&self.at.to_string()),
            self.change,
            quoted(&self.object),
            quoted(&self.prev),
            self.seq
        )
    }

    /// `hex(SHA-256(canonical))`, what `hash` must be.
    pub fn digest(&self) -> String {
        hex::encode(Sha256::digest(self.canonical().as_bytes()))
    }
}

/// Where a chain breaks: the first entry that does not hold, and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("audit entry {seq}: {why}")]
pub struct Broken {
    /// The entry's sequence number (the one expected, when entries are
    /// missing).
    pub seq: i64,
    /// What does not hold.
    pub why: String,
}

/// A chain checked entry by entry, in sequence order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Chain {
    /// The last entry checked: its sequence number and hash (0 and
    /// [`GENESIS`] before any).
    pub head: (i64, String),
}

impl Default for Chain {
    fn default() -> Self {
        Chain {
            head: (0, GENESIS.to_owned()),
        }
    }
}

impl Chain {
    /// Checks the next entry: its number follows, it names the previous
    /// entry's hash, its change is JSON, and its hash is its content's.
    pub fn check(&mut self, e: &Entry) -> Result<(), Broken> {
        let (seq, prev) = &self.head;
        let expected = seq + 1;
        if e.seq != expected {
            return Err(Broken {
                seq: expected,
                why: format!(
                    "missing: the entry after {seq} is numbered {} (an entry deleted, or one \
                     inserted out of sequence)",
                    e.seq
                ),
            });
        }
        if &e.prev != prev {
            return Err(Broken {
                seq: e.seq,
                why: format!(
                    "its prev {} is not the hash of entry {seq}, {prev} (an entry before it \
                     was edited, deleted or inserted)",
                    e.prev
                ),
            });
        }
        if serde_json::from_str::<Value>(&e.change).is_err() {
            return Err(Broken {
                seq: e.seq,
                why: "its change is not JSON (edited)".into(),
            });
        }
        let digest = e.digest();
        if digest != e.hash {
            return Err(Broken {
                seq: e.seq,
                why: format!(
                    "its hash {} is not the hash of its content, {digest} (the entry was edited, or forged)",
                    e.hash
                ),
            });
        }
        self.head = (e.seq, e.hash.clone());
        Ok(())
    }
}

/// The object path of a calibration.
pub fn calibration(id: uuid::Uuid) -> String {
    format!("calibrations/{id}")
}

/// One entry of the audit trail.
#[derive(Debug, Serialize, ToSchema)]
pub struct AuditEntry {
    /// Its place in the chain, from 1, without gaps.
    #[schema(minimum = 1)]
    pub seq: i64,
    /// When it happened.
    at: Timestamp,
    /// Who did it.
    actor: Actor,
    /// What was done: `calibration.submitted`, `calibration.approve`,
    /// `calibration.reject`, `calibration.withdraw`, `calibration.supersede`,
    /// `calibration.confirm`, `token.create`, `token.revoke`,
    /// `sensor_type.put`, `sensor.retype`, `standard.put`, `customer.put`,
    /// `item.put` or `service.configure`.
    action: String,
    /// What it was done to: `calibrations/{id}`, `tokens/{id}`,
    /// `sensor-types/{id}`, `sensors/{id}`, `standards/{id}`,
    /// `customers/{id}`, `items/{sensor_id}` or `service`.
    object: String,
    /// The change, as recorded.
    #[schema(value_type = Object)]
    change: serde_json::Value,
    /// The previous entry's hash (64 zeros for the first).
    prev: String,
    /// SHA-256 (hex) of the entry's canonical form, which names `prev`.
    hash: String,
}

impl From<Entry> for AuditEntry {
    fn from(e: Entry) -> AuditEntry {
        let change = serde_json::from_str(&e.change).unwrap_or(serde_json::Value::String(e.change));
        AuditEntry {
            seq: e.seq,
            at: e.at,
            actor: e.actor,
            action: e.action,
            object: e.object,
            change,
            prev: e.prev,
            hash: e.hash,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn event(n: u8) -> Event {
        let mut change = serde_json::Map::new();
        change.insert("zeta".into(), Value::from(n));
        change.insert("alpha".into(), Value::from("a \"quoted\"\nline"));
        Event::new(
            Timestamp::parse("2026-11-25T10:00:00Z").unwrap(),
            Actor {
                token_id: "0193a2b4-0000-7000-8000-000000000001".into(),
                role: "reviewer".into(),
                holder: Some("Ada Lovelace".into()),
            },
            "calibration.approve",
            format!("calibrations/{n}"),
            change,
        )
    }

    fn chain(n: u8) -> Vec<Entry> {
        let mut out: Vec<Entry> = Vec::new();
        for i in 1..=n {
            let after = out.last().map(|e| (e.seq, e.hash.as_str()));
            let e = Entry::chain(after, event(i));
            out.push(e);
        }
        out
    }

    /// The canonical text and its SHA-256, against the text written out by
    /// hand and the digest computed independently (Python's hashlib over
    /// `json.dumps(…, sort_keys=True, separators=(",", ":"))` of the same
    /// object).
    #[test]
    fn canonical_form_and_hash_are_the_documented_ones() {
        let e = Entry::chain(None, event(1));
        assert_eq!(
            e.canonical(),
            r#"{"action":"calibration.approve","actor":{"holder":"Ada Lovelace","role":"reviewer","token_id":"0193a2b4-0000-7000-8000-000000000001"},"at":"2026-11-25T10:00:00.000000Z","change":{"alpha":"a \"quoted\"\nline","zeta":1},"object":"calibrations/1","prev":"0000000000000000000000000000000000000000000000000000000000000000","seq":1}"#
        );
        assert_eq!(
            e.hash,
            "d5a1088976e34ccba4b3b76c4f46d9fff13da7852e100babf31489580483edae"
        );
    }

    #[test]
    fn an_intact_chain_checks_and_ends_at_its_head() {
        let entries = chain(4);
        let mut c = Chain::default();
        for e in &entries {
            c.check(e).unwrap();
        }
        assert_eq!(c.head, (4, entries[3].hash.clone()));
        assert_eq!(entries[0].prev, GENESIS);
        assert_eq!(entries[2].prev, entries[1].hash);
    }

    fn first_break(entries: &[Entry]) -> Broken {
        let mut c = Chain::default();
        entries
            .iter()
            .find_map(|e| c.check(e).err())
            .expect("the chain breaks")
    }

    #[test]
    fn an_edited_entry_is_named() {
        let mut entries = chain(4);
        entries[1].change = r#"{"alpha":"forged","zeta":2}"#.into();
        let b = first_break(&entries);
        assert_eq!(b.seq, 2);
        assert!(b.why.contains("edited"), "{}", b.why);
    }

    #[test]
    fn an_edit_with_its_hash_recomputed_breaks_the_next_link() {
        let mut entries = chain(4);
        entries[1].actor.holder = Some("Mallory".into());
        entries[1].hash = entries[1].digest();
        let b = first_break(&entries);
        assert_eq!(b.seq, 3);
        assert!(b.why.contains("is not the hash of entry 2"), "{}", b.why);
    }

    #[test]
    fn a_deleted_entry_is_named_by_the_number_missing() {
        let mut entries = chain(4);
        entries.remove(2);
        let b = first_break(&entries);
        assert_eq!(b.seq, 3);
        assert!(b.why.contains("numbered 4"), "{}", b.why);
    }

    #[test]
    fn a_change_that_is_not_json_is_named() {
        let mut entries = chain(2);
        entries[0].change = "{".into();
        entries[0].hash = entries[0].digest();
        assert_eq!(first_break(&entries).seq, 1);
    }
}
