//! What the trail says every protected row must be: the entries replayed in
//! sequence order into, per object, the content its last entry vouches for.

use std::collections::HashMap;

use serde_json::Value;
use uuid::Uuid;

use crate::domain::audit::{Actor, Entry};
use crate::domain::timestamp::Timestamp;

/// A `calibration.submitted` entry.
#[derive(Debug, Clone)]
pub struct Submitted {
    /// Its sequence number.
    pub seq: i64,
    /// Who submitted it.
    pub by: Actor,
    /// The change.
    pub change: Value,
}

/// A signature's entry (`calibration.{action}`).
#[derive(Debug, Clone)]
pub struct Signed {
    /// Its sequence number.
    pub seq: i64,
    /// The act.
    pub action: String,
    /// Who signed.
    pub by: Actor,
    /// When.
    pub at: Timestamp,
    /// The change (`from`, `to`, `meaning`, `comment`, `superseded_by`, and
    /// the certificate an approval issued).
    pub change: Value,
}

/// The digests an entry recorded of one issued revision.
#[derive(Debug, Clone, PartialEq)]
pub struct Issued {
    /// The entry.
    pub seq: i64,
    /// The HTML's SHA-256.
    pub html_sha256: Option<String>,
    /// The DCC's.
    pub dcc_sha256: Option<String>,
}

/// A token's entries.
#[derive(Debug, Clone, Default)]
pub struct Token {
    /// `token.create`'s change.
    pub created: Option<Value>,
    /// When `token.revoke` says it was revoked.
    pub revoked_at: Option<Timestamp>,
}

/// Everything the trail vouches for, by object.
#[derive(Debug, Default)]
pub struct Expected {
    /// Each calibration's `calibration.submitted`.
    pub calibrations: HashMap<Uuid, Submitted>,
    /// Each calibration's signatures, in order.
    pub signatures: HashMap<Uuid, Vec<Signed>>,
    /// Each issued revision's digests, by calibration and revision.
    pub certificates: HashMap<(Uuid, u32), Issued>,
    /// Each definition's last `{kind}.put`: its definition, by object path
    /// (`standards/DH-1`).
    pub definitions: HashMap<String, Value>,
    /// Each token's entries, by id (as the entries name it).
    pub tokens: HashMap<String, Token>,
    /// Each nonconformity's entry: its standard and change.
    pub nonconformities: HashMap<Uuid, (String, Value)>,
    /// The calibrations each nonconformity held as they were stored.
    pub held_on_storing: HashMap<Uuid, Vec<Uuid>>,
    /// Each sensor's assigned type, as the entries assign it; `None` when
    /// an entry from before types were recorded assigns one unknown.
    pub sensor_types: HashMap<String, Option<String>>,
    /// Rows adopted by `accelcal audit adopt`: the SHA-256 of each, by
    /// object.
    pub adopted: HashMap<String, String>,
}

fn text<'a>(v: &'a Value, key: &str) -> Option<&'a str> {
    v.get(key).and_then(Value::as_str)
}

impl Expected {
    /// Takes entry `e` into account (entries in sequence order).
    pub fn take(&mut self, e: &Entry) {
        let change: Value = serde_json::from_str(&e.change).unwrap_or(Value::Null);
        let calibration = e
            .object
            .strip_prefix("calibrations/")
            .and_then(|id| Uuid::try_parse(id).ok());
        match (e.action.as_str(), calibration) {
            ("calibration.submitted", Some(id)) => {
                if let Some(sensor) = text(&change, "sensor_id") {
                    match change.get("assigns_type").and_then(Value::as_bool) {
                        Some(true) => {
                            let t = text(&change, "sensor_type").map(str::to_owned);
                            self.sensor_types.insert(sensor.to_owned(), t);
                        }
                        Some(false) => {}
                        // Recorded before the entry said: the sensor's type
                        // is not known from the trail.
                        None => {
                            self.sensor_types.insert(sensor.to_owned(), None);
                        }
                    }
                }
                self.calibrations.insert(
                    id,
                    Submitted {
                        seq: e.seq,
                        by: e.actor.clone(),
                        change,
                    },
                );
            }
            ("certificate.issue" | "certificate.amend", Some(id)) => {
                if let Some(n) = change.get("revision").and_then(Value::as_u64) {
                    self.certificates
                        .insert((id, n as u32), issued(e.seq, &change));
                }
            }
            (action, Some(id)) if action.starts_with("calibration.") => {
                let act = action.trim_start_matches("calibration.").to_owned();
                if let Some(c) = change.get("certificate")
                    && let Some(n) = c.get("revision").and_then(Value::as_u64)
                {
                    self.certificates.insert((id, n as u32), issued(e.seq, c));
                }
                if let Some(ncs) = change.get("nonconformities").and_then(Value::as_array) {
                    for nc in ncs.iter().filter_map(Value::as_str) {
                        if let Ok(nc) = Uuid::try_parse(nc) {
                            self.held_on_storing.entry(nc).or_default().push(id);
                        }
                    }
                }
                self.signatures.entry(id).or_default().push(Signed {
                    seq: e.seq,
                    action: act,
                    by: e.actor.clone(),
                    at: e.at,
                    change,
                });
            }
            ("standard.nonconformity", _) => {
                if let Some(id) =
                    text(&change, "nonconformity_id").and_then(|i| Uuid::try_parse(i).ok())
                {
                    let standard = e.object.trim_start_matches("standards/").to_owned();
                    self.nonconformities.insert(id, (standard, change));
                }
            }
            ("token.create", _) => {
                let id = e.object.trim_start_matches("tokens/").to_owned();
                self.tokens.entry(id).or_default().created = Some(change);
            }
            ("token.revoke", _) => {
                let id = e.object.trim_start_matches("tokens/").to_owned();
                self.tokens.entry(id).or_default().revoked_at = Some(e.at);
            }
            ("sensor.retype", _) => {
                let sensor = e.object.trim_start_matches("sensors/").to_owned();
                let t = text(&change, "sensor_type").map(str::to_owned);
                self.sensor_types.insert(sensor, t);
            }
            ("audit.adopt", _) => {
                if let Some(d) = text(&change, "sha256") {
                    self.adopted.insert(e.object.clone(), d.to_owned());
                }
            }
            (action, _) if action.ends_with(".put") => {
                if let Some(d) = change.get("definition") {
                    self.definitions.insert(e.object.clone(), d.clone());
                }
            }
            _ => {}
        }
    }
}

fn issued(seq: i64, c: &Value) -> Issued {
    Issued {
        seq,
        html_sha256: text(c, "html_sha256").map(str::to_owned),
        dcc_sha256: text(c, "dcc_sha256").map(str::to_owned),
    }
}
