//! Live events (issue 47 item 1): what a dashboard or a control system
//! would act on, read from the audit trail.
//!
//! Every act that changes what a reader would act on already writes an
//! audit entry in its own transaction ([`super::audit`]), and the trail
//! gives each a place in one total order (`seq`, without gaps, in the
//! order the acts committed). An event is such an entry seen from outside:
//! its `seq` is the event's id and sequence, so a client that resumes
//! after the last id it saw misses nothing and sees nothing twice, and the
//! trail — kept for good — is the events' retention. Acts that change
//! nothing a reader acts on (tokens, definitions, the service's settings, a
//! reprocessing that confirmed every number) are not events.
//!
//! | audit action | event type |
//! |---|---|
//! | `calibration.submitted` | `calibration.stored` |
//! | `calibration.approve` from `under_review` | `calibration.released` |
//! | `calibration.approve` otherwise | `calibration.approved` |
//! | `calibration.reject`, `.withdraw`, `.supersede`, `.hold` | `calibration.rejected`, `.withdrawn`, `.superseded`, `.held` |
//! | `certificate.issue`, `certificate.amend` | `certificate.issued`, `certificate.amended` |
//! | `sensor.retype` | `sensor.retyped` |
//! | `sensor.status` | `sensor.status` (by the clock: due soon, overdue) |
//! | `standard.nonconformity` | `standard.nonconformity` |
//!
//! An approval that issued the calibration's certificate is one act and
//! one event, `calibration.approved` with its `certificate`; a filter on
//! `certificate.issued` selects it too ([`LiveEvent::is`]).
//!
//! **What the coefficients did.** An act on a calibration records, in its
//! own transaction, what it did to the coefficients its sensor's reads
//! serve ([`Effect`]) on both bases (`--require-approval` or not), and the
//! event says it on the service's basis ([`Served`]): whether they changed
//! — another calibration served, none any more, or the served one held or
//! released — and, when they did, the calibration served now. A control
//! system that sees `changed: false` keeps what it loaded. Entries recorded
//! before this was recorded say nothing (no `coefficients`).

use serde::{Deserialize, Serialize};
use serde_json::Value;
use utoipa::ToSchema;
use uuid::Uuid;

use super::audit::Entry;
use super::review::{Basis, State};
use super::timestamp::Timestamp;

/// What happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
pub enum EventType {
    /// A calibration was stored.
    #[serde(rename = "calibration.stored")]
    CalibrationStored,
    /// A reviewer approved a calibration.
    #[serde(rename = "calibration.approved")]
    CalibrationApproved,
    /// A reviewer rejected a calibration.
    #[serde(rename = "calibration.rejected")]
    CalibrationRejected,
    /// A calibration was withdrawn.
    #[serde(rename = "calibration.withdrawn")]
    CalibrationWithdrawn,
    /// A corrected calibration replaced it (`change.superseded_by`).
    #[serde(rename = "calibration.superseded")]
    CalibrationSuperseded,
    /// Held for a nonconforming standard: its coefficients are not usable.
    #[serde(rename = "calibration.held")]
    CalibrationHeld,
    /// A held calibration approved again: usable once more.
    #[serde(rename = "calibration.released")]
    CalibrationReleased,
    /// A certificate issued after its calibration's approval.
    #[serde(rename = "certificate.issued")]
    CertificateIssued,
    /// A certificate amended (a new revision).
    #[serde(rename = "certificate.amended")]
    CertificateAmended,
    /// A sensor given a (new) type, so judged by other limits.
    #[serde(rename = "sensor.retyped")]
    SensorRetyped,
    /// A reference standard found nonconforming.
    #[serde(rename = "standard.nonconformity")]
    StandardNonconformity,
    /// A sensor's status changed by the clock: its due date came within 30
    /// days (`due_soon`) or passed (`overdue`); `change.from`, `.to`,
    /// `.due_at`.
    #[serde(rename = "sensor.status")]
    SensorStatus,
}

impl EventType {
    /// Every type, in the order of the module's table.
    pub const ALL: [EventType; 12] = [
        EventType::CalibrationStored,
        EventType::CalibrationApproved,
        EventType::CalibrationRejected,
        EventType::CalibrationWithdrawn,
        EventType::CalibrationSuperseded,
        EventType::CalibrationHeld,
        EventType::CalibrationReleased,
        EventType::CertificateIssued,
        EventType::CertificateAmended,
        EventType::SensorRetyped,
        EventType::StandardNonconformity,
        EventType::SensorStatus,
    ];

    /// The wire name (`calibration.stored`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            EventType::CalibrationStored => "calibration.stored",
            EventType::CalibrationApproved => "calibration.approved",
            EventType::CalibrationRejected => "calibration.rejected",
            EventType::CalibrationWithdrawn => "calibration.withdrawn",
            EventType::CalibrationSuperseded => "calibration.superseded",
            EventType::CalibrationHeld => "calibration.held",
            EventType::CalibrationReleased => "calibration.released",
            EventType::CertificateIssued => "certificate.issued",
            EventType::CertificateAmended => "certificate.amended",
            EventType::SensorRetyped => "sensor.retyped",
            EventType::StandardNonconformity => "standard.nonconformity",
            EventType::SensorStatus => "sensor.status",
        }
    }

    /// The type named `s`, if any.
    pub fn parse(s: &str) -> Option<EventType> {
        EventType::ALL.into_iter().find(|t| t.as_str() == s)
    }

    /// The type of the audit entry's act, when it is an event: `from` is
    /// the state a signature's change records it left.
    fn of(action: &str, from: Option<&str>) -> Option<EventType> {
        Some(match action {
            "calibration.submitted" => EventType::CalibrationStored,
            "calibration.approve" if from == Some("under_review") => EventType::CalibrationReleased,
            "calibration.approve" => EventType::CalibrationApproved,
            "calibration.reject" => EventType::CalibrationRejected,
            "calibration.withdraw" => EventType::CalibrationWithdrawn,
            "calibration.supersede" => EventType::CalibrationSuperseded,
            "calibration.hold" => EventType::CalibrationHeld,
            "certificate.issue" => EventType::CertificateIssued,
            "certificate.amend" => EventType::CertificateAmended,
            "sensor.retype" => EventType::SensorRetyped,
            "standard.nonconformity" => EventType::StandardNonconformity,
            "sensor.status" => EventType::SensorStatus,
            _ => return None,
        })
    }
}

/// One event, as `GET /v1/events` sends it (the `data:` of an SSE event
/// whose `id:` is `seq` and `event:` is `type`).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct LiveEvent {
    /// The event's id and place in the one order of events: the sequence
    /// number of the audit entry it is.
    pub seq: i64,
    /// When the act happened.
    #[schema(value_type = String, format = DateTime)]
    pub at: Timestamp,
    /// What happened.
    #[serde(rename = "type")]
    pub kind: EventType,
    /// The sensor it concerns, if one.
    pub sensor_id: Option<String>,
    /// The calibration it concerns, if one.
    pub calibration_id: Option<Uuid>,
    /// What the act recorded (the audit entry's change): for a review, the
    /// state `from` and `to`; for a supersession, `superseded_by`; for a
    /// stored calibration, its `performed_at` and the digests of what was
    /// stored.
    #[schema(value_type = Object)]
    pub change: Value,
    /// For an act on a calibration: what it did to the coefficients the
    /// sensor's reads serve (on the service's basis). Absent for other
    /// events, and for acts recorded before this was.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub coefficients: Option<Served>,
}

/// What one act did to the coefficients a sensor's reads serve
/// (`GET /v1/sensors/{id}/coefficients`, compensation) on one basis.
///
/// `changed` when what they serve after the act is not what they served
/// before: another calibration (a newer one stored, the served one
/// withdrawn, rejected or superseded, an approval with
/// `--require-approval`), none any more, or the same calibration held for
/// a nonconforming standard or released — its coefficients become
/// unusable, or usable again. Then `calibration_id` is the calibration
/// served now (`null`: none); when nothing changed it is absent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ToSchema)]
pub struct Served {
    /// Whether the served coefficients changed.
    pub changed: bool,
    /// When they changed: the calibration served now (`null`: none).
    #[schema(nullable)]
    pub calibration_id: Option<Uuid>,
}

/// What a basis serves at one moment: the calibration (`None`: none) and
/// whether its state leaves its coefficients usable (not held).
pub type Serving = Option<(Uuid, bool)>;

impl Served {
    /// Nothing changed.
    pub const UNCHANGED: Served = Served {
        changed: false,
        calibration_id: None,
    };

    /// The change from serving `before` to serving `after`.
    pub fn between(before: Serving, after: Serving) -> Served {
        if before == after {
            Served::UNCHANGED
        } else {
            Served {
                changed: true,
                calibration_id: after.map(|(id, _)| id),
            }
        }
    }

    /// What the sensor's row serves on [`Basis::NotRejected`] when its
    /// latest calibration is `latest`, calibration `acted` (the act's) being
    /// in state `state`: the others' states are not the act's, so the same
    /// before and after it.
    pub fn serving(latest: Option<Uuid>, acted: Uuid, state: State) -> Serving {
        latest.map(|id| (id, id != acted || state != State::UnderReview))
    }

    fn to_value(self) -> Value {
        let mut m = serde_json::Map::new();
        m.insert("changed".into(), Value::Bool(self.changed));
        if self.changed {
            m.insert(
                "calibration_id".into(),
                self.calibration_id
                    .map_or(Value::Null, |id| Value::String(id.to_string())),
            );
        }
        Value::Object(m)
    }

    fn from_value(v: &Value) -> Option<Served> {
        let changed = v.get("changed")?.as_bool()?;
        let calibration_id = match v.get("calibration_id") {
            Some(Value::String(s)) if changed => Some(Uuid::try_parse(s).ok()?),
            _ => None,
        };
        Some(Served {
            changed,
            calibration_id,
        })
    }
}

impl Serialize for Served {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.to_value().serialize(s)
    }
}

/// What one act did to the served coefficients on each basis, as its audit
/// entry records it (`change.coefficients`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Effect {
    /// Every calibration not rejected, withdrawn or superseded counts.
    pub not_rejected: Served,
    /// Approved calibrations only (`--require-approval`).
    pub approved_only: Served,
}

impl Effect {
    /// Of storing calibration `id`, which became its sensor's latest
    /// (`latest`) or not: served at once without `--require-approval`
    /// when latest; never served at once with it (stored unapproved).
    pub fn stored(id: Uuid, latest: bool) -> Effect {
        Effect {
            not_rejected: if latest {
                Served::between(None, Some((id, true)))
            } else {
                Served::UNCHANGED
            },
            approved_only: Served::UNCHANGED,
        }
    }

    /// Of holding calibration `id` as it is stored: its coefficients, if
    /// served (its sensor's `latest`), become unusable.
    pub fn held_on_storing(id: Uuid, latest: bool) -> Effect {
        Effect {
            not_rejected: if latest {
                Served::between(Some((id, true)), Some((id, false)))
            } else {
                Served::UNCHANGED
            },
            approved_only: Served::UNCHANGED,
        }
    }

    /// Of a signature moving calibration `id` from state `from` to `to`:
    /// `latest` is its sensor's latest calibration (the row's, what is
    /// served without `--require-approval`) before and after the act;
    /// `approved` its latest approved calibration before and after, read
    /// when the act could change it ([`Effect::touches_approved`]),
    /// unchanged otherwise.
    pub fn signed(
        id: Uuid,
        from: State,
        to: State,
        latest: (Option<Uuid>, Option<Uuid>),
        approved: Option<(Option<Uuid>, Option<Uuid>)>,
    ) -> Effect {
        let approved_only = approved.map_or(Served::UNCHANGED, |(before, after)| {
            Served::between(before.map(|c| (c, true)), after.map(|c| (c, true)))
        });
        Effect {
            not_rejected: Served::between(
                Served::serving(latest.0, id, from),
                Served::serving(latest.1, id, to),
            ),
            approved_only,
        }
    }

    /// Whether a signature moving a calibration from `from` to `to` can
    /// change what `--require-approval` serves: only when it was or
    /// becomes approved.
    pub fn touches_approved(from: State, to: State) -> bool {
        from.counts(Basis::ApprovedOnly) || to.counts(Basis::ApprovedOnly)
    }

    /// The change's value (`{"not_rejected": …, "approved_only": …}`).
    pub fn to_value(self) -> Value {
        serde_json::json!({
            "not_rejected": self.not_rejected.to_value(),
            "approved_only": self.approved_only.to_value(),
        })
    }

    /// What the entry's change `change` records on `basis`, if anything.
    pub fn on(change: &Value, basis: Basis) -> Option<Served> {
        let key = match basis {
            Basis::NotRejected => "not_rejected",
            Basis::ApprovedOnly => "approved_only",
        };
        Served::from_value(change.get("coefficients")?.get(key)?)
    }
}

impl LiveEvent {
    /// The event an audit entry is, if any. Its sensor is the one the
    /// entry names (a stored calibration's `sensor_id`, a retyped sensor's
    /// object); for the other acts on a calibration the caller looks it up
    /// ([`LiveEvent::needs_sensor`]). What the coefficients did is told on
    /// `basis`, the service's.
    pub fn from_entry(e: &Entry, basis: Basis) -> Option<LiveEvent> {
        let change: Value = serde_json::from_str(&e.change).unwrap_or(Value::Null);
        let from = change.get("from").and_then(Value::as_str);
        let kind = EventType::of(&e.action, from)?;
        let calibration_id = e
            .object
            .strip_prefix("calibrations/")
            .and_then(|id| Uuid::try_parse(id).ok());
        let sensor_id = match kind {
            EventType::SensorRetyped | EventType::SensorStatus => {
                e.object.strip_prefix("sensors/").map(str::to_owned)
            }
            _ => change
                .get("sensor_id")
                .and_then(Value::as_str)
                .map(str::to_owned),
        };
        let coefficients = Effect::on(&change, basis);
        // Said once, on the service's basis, rather than both bases twice.
        let mut change = change;
        if let Some(m) = change.as_object_mut() {
            m.remove("coefficients");
        }
        Some(LiveEvent {
            seq: e.seq,
            at: e.at,
            kind,
            sensor_id,
            calibration_id,
            change,
            coefficients,
        })
    }

    /// The calibration whose sensor this event must be given (none named).
    pub fn needs_sensor(&self) -> Option<Uuid> {
        self.calibration_id.filter(|_| self.sensor_id.is_none())
    }

    /// Whether this event is of type `t`: its own, or `certificate.issued`
    /// for an approval that issued one.
    pub fn is(&self, t: EventType) -> bool {
        self.kind == t
            || (t == EventType::CertificateIssued
                && self.kind == EventType::CalibrationApproved
                && self.change.get("certificate").is_some_and(|c| !c.is_null()))
    }
}

/// Which events a client asked for: all, or those of the named sensors
/// and of the named types (each list empty: any).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Filter {
    /// Only events of these sensors.
    pub sensors: Vec<String>,
    /// Only events of these types.
    pub types: Vec<EventType>,
}

impl Filter {
    /// Whether `e` passes.
    pub fn admits(&self, e: &LiveEvent) -> bool {
        (self.sensors.is_empty()
            || e.sensor_id
                .as_ref()
                .is_some_and(|s| self.sensors.contains(s)))
            && (self.types.is_empty() || self.types.iter().any(|t| e.is(*t)))
    }
}

#[cfg(test)]
mod tests;
