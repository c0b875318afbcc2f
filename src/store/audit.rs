//! What each stored act appends to the audit trail ([`crate::domain::audit`]),
//! and how the trail is read: shared by both engines, which append the
//! events below in the transaction of the act.

use serde::Serialize;
use serde_json::{Map, Value, json};
use sha2::{Digest, Sha256};
use uuid::Uuid;

use super::NewCalibration;
use crate::domain::audit::{self, Actor, Event};
use crate::domain::events::Effect;
use crate::domain::review::{Signature, State};
use crate::domain::timestamp::Timestamp;

/// Which entries to read, in sequence order.
#[derive(Debug, Clone, Default)]
pub struct AuditQuery {
    /// Only entries about this object (`calibrations/{id}`, `tokens/{id}`,
    /// `sensors/{id}`, …).
    pub object: Option<String>,
    /// Only entries by this token id or holder.
    pub actor: Option<String>,
    /// Only entries at or after this instant.
    pub from: Option<Timestamp>,
    /// Only entries at or before this instant.
    pub to: Option<Timestamp>,
    /// Only entries after this sequence number (the page's cursor).
    pub after: i64,
    /// Page size.
    pub limit: usize,
}

impl AuditQuery {
    /// The token id `actor` names in the simple spelling the trail records
    /// for tokens (a UUID without hyphens), whichever spelling was given
    /// (`/v1/tokens` writes it with hyphens); anything else as it is
    /// (`env-admin`). The filter matches a token id as given or in this
    /// spelling.
    pub fn actor_token(&self) -> Option<String> {
        self.actor.as_ref().map(|a| {
            uuid::Uuid::parse_str(a).map_or_else(|_| a.clone(), |id| id.simple().to_string())
        })
    }
}

fn object(change: Value) -> Map<String, Value> {
    match change {
        Value::Object(m) => m,
        other => Map::from_iter([("value".to_owned(), other)]),
    }
}

fn sha256(bytes: &[u8]) -> String {
    hex::encode(Sha256::digest(bytes))
}

/// A calibration's `calibration.submitted` entry before it is stored:
/// everything of it but the actor and the effect, which only the store's
/// transaction knows. Built by the request ([`submitted`]), so that the
/// digests — most of the entry's cost — are computed beside the other
/// requests rather than by the one writer, and on PostgreSQL not while the
/// writer holds its sensors' rows. Its change is kept as canonical JSON
/// text on either side of where the effect goes (`coefficients`, the
/// second key in byte order), so that the writer only joins three strings.
#[derive(Debug, Clone)]
pub struct Submitted {
    at: Timestamp,
    id: Uuid,
    /// `{"assigns_type":…,"coefficients":`
    head: String,
    /// `,"content_type":…}`: the rest of the change.
    tail: String,
}

/// `calibration.submitted`: a calibration stored, by the token that
/// submitted it, at its reception; the change names its sensor, the SHA-256
/// of its submission and of its result document — so that the trail also
/// vouches for the stored bytes — the SHA-256 of its served columns
/// (`row_sha256`, [`super::verify`]), its media type, and the sensor type
/// in force and whether it became the sensor's; and what storing it did
/// to the coefficients served (the effect, given to
/// [`Submitted::event`]), put in the change as it is built rather than
/// parsed back in ([`with_effect`]): this is every submission's entry.
pub fn submitted(n: &NewCalibration) -> Submitted {
    // The keys after `coefficients`, in byte order as a map writes them.
    let rest = json!({
            "sensor_id": n.sensor_id,
            "station_id": n.station_id,
            "performed_at": n.performed_at.to_string(),
            "submission_sha256": sha256(&n.submission),
            "result_sha256": sha256(&n.result),
            "row_sha256": super::verify::rows::columns_digest(n),
            "content_type": n.content_type,
            "sensor_type": n.sensor_type,
    })
    .to_string();
    Submitted {
        at: n.received_at,
        id: n.id,
        head: format!(r#"{{"assigns_type":{},"coefficients":"#, n.assigns_type),
        // `rest` is a non-empty object: its `{` becomes the comma.
        tail: format!(",{}", &rest[1..]),
    }
}

/// The action of [`Submitted`]'s entries.
pub const SUBMITTED: &str = "calibration.submitted";

impl Submitted {
    /// The change's text before and after its effect, for a writer that
    /// joins them in SQL, where it learns the effect
    /// (`crate::store::postgres::batch`): `head + effect + tail` is
    /// [`Submitted::event`]'s change.
    pub fn around_effect(&self) -> (&str, &str) {
        (&self.head, &self.tail)
    }

    /// When it was received.
    pub fn at(&self) -> Timestamp {
        self.at
    }

    /// The entry, by `by`, with what storing it did (`effect`).
    pub fn event(&self, by: Actor, effect: Effect) -> Event {
        let effect = effect.to_value().to_string();
        let mut change = String::with_capacity(self.head.len() + effect.len() + self.tail.len());
        change.push_str(&self.head);
        change.push_str(&effect);
        change.push_str(&self.tail);
        Event {
            at: self.at,
            actor: by,
            action: SUBMITTED.into(),
            object: audit::calibration(self.id),
            change,
        }
    }
}

/// `calibration.{approve, reject, withdraw, supersede, confirm}`: a
/// signature, by its signer, from the state `from`.
pub fn signed(id: Uuid, s: &Signature, from: State) -> Event {
    Event::new(
        s.signed_at,
        Actor {
            token_id: s.token_id.clone(),
            role: s.role.as_str().into(),
            holder: s.holder.clone(),
        },
        &format!("calibration.{}", s.action.as_str()),
        audit::calibration(id),
        object(json!({
            "from": from.as_str(),
            "to": s.state.as_str(),
            "meaning": s.meaning,
            "comment": s.comment,
            "superseded_by": s.superseded_by,
        })),
    )
}

/// `e` with what its act did to the coefficients its sensor's reads
/// serve (`change.coefficients`, [`Effect`]): recorded in the act's own
/// transaction, told by its event ([`crate::domain::events`]).
pub fn with_effect(mut e: Event, effect: Effect) -> Event {
    let mut change: Map<String, Value> = serde_json::from_str(&e.change).unwrap_or_default();
    change.insert("coefficients".into(), effect.to_value());
    e.change = Value::Object(change).to_string();
    e
}

/// [`signed`] of a hold placed as a calibration is stored, naming the
/// nonconformities that hold it.
pub fn held_on_storing(id: Uuid, s: &Signature, nonconformities: &[Uuid]) -> Event {
    let mut e = signed(id, s, State::Submitted);
    let mut change: Map<String, Value> = serde_json::from_str(&e.change).unwrap_or_default();
    change.insert("nonconformities".into(), json!(nonconformities));
    e.change = Value::Object(change).to_string();
    e
}

/// [`signed`] of an approval that issued the certificate `c` (revision 1):
/// the change also names the revision and the SHA-256 of each document.
pub fn signed_issuing(
    id: Uuid,
    s: &Signature,
    from: State,
    c: &crate::store::IssuedCertificate,
) -> Event {
    let mut e = signed(id, s, from);
    let mut change: Map<String, Value> = serde_json::from_str(&e.change).unwrap_or_default();
    change.insert("certificate".into(), issued(c));
    e.change = Value::Object(change).to_string();
    e
}

/// What the trail records of an issued revision: its number, the SHA-256
/// of each document, why it has no DCC, and the reason of an amendment.
fn issued(c: &crate::store::IssuedCertificate) -> Value {
    json!({
        "revision": c.revision,
        "html_sha256": c.html_sha256,
        "dcc_sha256": c.dcc_sha256,
        "dcc_missing": c.dcc_missing,
        "reason": c.reason,
    })
}

/// `certificate.issue` (a revision 1 issued after its approval: a
/// calibration approved before certificates were issued at approval) or
/// `certificate.amend`: a revision of calibration `c`'s certificate, by
/// whoever issued it.
pub fn certificate(c: &crate::store::IssuedCertificate) -> Event {
    let action = if c.revision == 1 {
        "certificate.issue"
    } else {
        "certificate.amend"
    };
    Event::new(
        c.issued_at,
        c.issued_by.clone(),
        action,
        audit::calibration(c.calibration_id),
        object(issued(c)),
    )
}

/// `{kind}.put`: a definition (sensor type, standard, customer, item)
/// created or replaced, with the whole new definition.
pub fn put<T: Serialize>(
    kind: &str,
    object_path: String,
    created: bool,
    definition: &T,
    at: Timestamp,
    by: Actor,
) -> Event {
    let definition = serde_json::to_value(definition).unwrap_or(Value::Null);
    Event::new(
        at,
        by,
        &format!("{kind}.put"),
        object_path,
        object(json!({ "created": created, "definition": definition })),
    )
}

/// `sensor.retype`: a sensor given a type.
pub fn retyped(sensor_id: &str, type_id: &str, at: Timestamp, by: Actor) -> Event {
    Event::new(
        at,
        by,
        "sensor.retype",
        format!("sensors/{sensor_id}"),
        object(json!({ "sensor_type": type_id })),
    )
}

/// `sensor.status`: a sensor's status changed by the clock, to `to` with
/// its due date `due_at`, from the status last announced for that due date
/// (`None`: none was).
pub fn status_changed(
    sensor_id: &str,
    from: Option<crate::domain::status::Status>,
    to: crate::domain::status::Status,
    due_at: Timestamp,
    at: Timestamp,
) -> Event {
    Event::new(
        at,
        Actor::service(),
        "sensor.status",
        format!("sensors/{sensor_id}"),
        object(json!({
            "from": from.map(|s| s.as_str()),
            "to": to.as_str(),
            "due_at": due_at.to_string(),
        })),
    )
}

/// `token.create`: a token issued — never its secret or the hash stored of
/// it, but the SHA-256 of that hash, so that a hash swapped behind the
/// service's back (another secret let in) is found.
pub fn token_created(t: &crate::domain::tokens::TokenRecord, by: Actor) -> Event {
    Event::new(
        t.created_at,
        by,
        "token.create",
        format!("tokens/{}", t.id),
        object(json!({
            "role": t.role.as_str(),
            "station_id": t.station_id,
            "label": t.label,
            "holder": t.holder,
            "secret_hash_sha256": sha256(&t.secret_hash),
        })),
    )
}

/// `token.revoke`: a token revoked.
pub fn token_revoked(id: Uuid, at: Timestamp, by: Actor) -> Event {
    Event::new(at, by, "token.revoke", format!("tokens/{id}"), Map::new())
}

/// `webhook.put`: an endpoint registered or changed — its definition, and
/// for a new one the SHA-256 of its secret (never the secret).
pub fn webhook_put(
    def: &crate::domain::webhooks::Definition,
    secret: Option<&crate::domain::webhooks::Secret>,
    at: Timestamp,
    by: Actor,
) -> Event {
    let mut change = object(json!({
        "url": def.url,
        "event_types": def.event_types,
        "sensors": def.sensors,
        "description": def.description,
    }));
    if let Some(s) = secret {
        change.insert("secret_sha256".into(), sha256(s.expose().as_bytes()).into());
    }
    Event::new(
        at,
        by,
        "webhook.put",
        format!("webhooks/{}", def.webhook_id),
        change,
    )
}

/// `webhook.rotate`: an endpoint's secret replaced (its SHA-256), the old
/// one signing until `overlap_until`.
pub fn webhook_rotated(
    id: &str,
    secret: &crate::domain::webhooks::Secret,
    overlap_until: Timestamp,
    at: Timestamp,
    by: Actor,
) -> Event {
    Event::new(
        at,
        by,
        "webhook.rotate",
        format!("webhooks/{id}"),
        object(json!({
            "secret_sha256": sha256(secret.expose().as_bytes()),
            "previous_until": overlap_until.to_string(),
        })),
    )
}

/// `webhook.redeliver`: an endpoint's deliveries started again after event
/// `after`.
pub fn webhook_redelivered(id: &str, after: i64, at: Timestamp, by: Actor) -> Event {
    Event::new(
        at,
        by,
        "webhook.redeliver",
        format!("webhooks/{id}"),
        object(json!({ "after": after })),
    )
}

/// `webhook.delete`: an endpoint deleted.
pub fn webhook_deleted(id: &str, at: Timestamp, by: Actor) -> Event {
    Event::new(
        at,
        by,
        "webhook.delete",
        format!("webhooks/{id}"),
        Map::new(),
    )
}

/// `service.configure`: the settings that change decisions, as the service
/// started with them (appended when they differ from the last recorded).
pub fn configured(settings: Map<String, Value>, at: Timestamp) -> Event {
    Event::new(
        at,
        Actor::service(),
        "service.configure",
        "service".into(),
        settings,
    )
}

/// The actor of a submission: its token with role and holder from the
/// tokens table (`role`, `holder` as read there; `None` when the token is
/// not there — the configured admin token, or a database copied without
/// it).
pub fn submitter(token_id: &str, found: Option<(String, Option<String>)>) -> Actor {
    match found {
        Some((role, holder)) => Actor {
            token_id: token_id.to_owned(),
            role,
            holder,
        },
        None if token_id == crate::domain::auth::ENV_ADMIN => Actor {
            token_id: token_id.to_owned(),
            role: "admin".into(),
            holder: None,
        },
        None => Actor {
            token_id: token_id.to_owned(),
            role: "unknown".into(),
            holder: None,
        },
    }
}

pub use super::verify::{Verified, VerifyError, verify};

/// `standard.nonconformity`: a standard found nonconforming, with its
/// window and the calibrations of it, each with its state then.
pub fn nonconformity(
    nc: &crate::domain::nonconformity::Nonconformity,
    concerned: &[(Uuid, State)],
) -> Event {
    Event::new(
        nc.recorded_at,
        nc.recorded_by.clone(),
        "standard.nonconformity",
        format!("standards/{}", nc.standard_id),
        object(json!({
            "nonconformity_id": nc.id,
            "found_at": nc.found_at.to_string(),
            "last_known_good_at": nc.last_known_good_at.map(|t| t.to_string()),
            "window_from": nc.window_from.to_string(),
            "reason": nc.reason,
            "calibrations": concerned.len(),
            "concerned": concerned
                .iter()
                .map(|(id, state)| json!({"calibration_id": id, "state_found": state.as_str()}))
                .collect::<Vec<_>>(),
        })),
    )
}

/// [`nonconformity`] of a nonconformity `put` with what it concerns (a
/// database copied by `accelcal migrate`).
pub fn traced(t: &crate::domain::nonconformity::Traced) -> Event {
    let concerned: Vec<(Uuid, State)> = t
        .calibrations
        .iter()
        .map(|c| (c.calibration_id, c.state_found))
        .collect();
    nonconformity(&t.nonconformity, &concerned)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::verify::rows::tests::single_axis;

    /// The entry as it was built before [`Submitted`] kept its change as
    /// text: one map of every key, the effect inserted, written — the
    /// definition [`Submitted::event`] must keep byte for byte.
    fn reference(n: &NewCalibration, by: Actor, effect: Effect) -> Event {
        let mut change = object(json!({
            "sensor_id": n.sensor_id,
            "station_id": n.station_id,
            "performed_at": n.performed_at.to_string(),
            "submission_sha256": sha256(&n.submission),
            "result_sha256": sha256(&n.result),
            "row_sha256": super::super::verify::rows::columns_digest(n),
            "content_type": n.content_type,
            "sensor_type": n.sensor_type,
            "assigns_type": n.assigns_type,
        }));
        change.insert("coefficients".into(), effect.to_value());
        Event::new(
            n.received_at,
            by,
            "calibration.submitted",
            audit::calibration(n.id),
            change,
        )
    }

    #[test]
    fn a_submitted_entry_is_its_maps_canonical_text() {
        let by = Actor {
            token_id: "env-admin".into(),
            role: "admin".into(),
            holder: None,
        };
        let full = single_axis();
        let bare = NewCalibration {
            station_id: None,
            sensor_type: None,
            assigns_type: false,
            ..single_axis()
        };
        for n in [&full, &bare] {
            for latest in [true, false] {
                let effect = Effect::stored(n.id, latest);
                let got = submitted(n).event(by.clone(), effect);
                assert_eq!(got, reference(n, by.clone(), effect));
                let change: Value = serde_json::from_str(&got.change).expect("JSON");
                assert_eq!(change["coefficients"], effect.to_value());
                assert_eq!(change["assigns_type"], json!(n.assigns_type));
            }
        }
    }
}
