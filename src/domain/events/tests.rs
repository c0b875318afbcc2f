//! Tests of [`super`].

use super::*;
use crate::domain::audit::Actor;
use serde_json::json;

const CAL: &str = "0193a2b4-0000-7000-8000-00000000000c";

fn entry(seq: i64, action: &str, object: &str, change: Value) -> Entry {
    Entry {
        seq,
        at: Timestamp::parse("2026-11-28T08:00:00Z").unwrap(),
        actor: Actor::service(),
        action: action.into(),
        object: object.into(),
        change: change.to_string(),
        prev: String::new(),
        hash: String::new(),
    }
}

fn calibration(seq: i64, action: &str, change: Value) -> Option<LiveEvent> {
    LiveEvent::from_entry(
        &entry(seq, action, &format!("calibrations/{CAL}"), change),
        Basis::NotRejected,
    )
}

/// A stored calibration names its sensor; the event carries it, the
/// calibration from the object, and the entry's seq, time and change.
#[test]
fn a_stored_calibration_is_an_event_of_its_sensor() {
    let e = calibration(
        7,
        "calibration.submitted",
        json!({"sensor_id": "ACC-1", "performed_at": "2026-11-28T07:00:00Z"}),
    )
    .unwrap();
    assert_eq!(e.seq, 7);
    assert_eq!(e.kind, EventType::CalibrationStored);
    assert_eq!(e.sensor_id.as_deref(), Some("ACC-1"));
    assert_eq!(e.calibration_id, Some(Uuid::try_parse(CAL).unwrap()));
    assert_eq!(e.change["performed_at"], "2026-11-28T07:00:00Z");
    assert_eq!(e.needs_sensor(), None);
    assert_eq!(
        serde_json::to_value(&e).unwrap()["type"],
        "calibration.stored"
    );
}

/// A signature's type follows its action, and an approval of a held
/// calibration (from `under_review`) is its release; its sensor must be
/// looked up.
#[test]
fn reviews_are_typed_by_action_and_state() {
    let cases = [
        (
            "calibration.approve",
            "submitted",
            EventType::CalibrationApproved,
        ),
        (
            "calibration.approve",
            "under_review",
            EventType::CalibrationReleased,
        ),
        (
            "calibration.reject",
            "submitted",
            EventType::CalibrationRejected,
        ),
        (
            "calibration.withdraw",
            "approved",
            EventType::CalibrationWithdrawn,
        ),
        (
            "calibration.supersede",
            "approved",
            EventType::CalibrationSuperseded,
        ),
        ("calibration.hold", "approved", EventType::CalibrationHeld),
    ];
    for (action, from, kind) in cases {
        let e = calibration(3, action, json!({"from": from, "to": "x"})).unwrap();
        assert_eq!(e.kind, kind, "{action} from {from}");
        assert_eq!(e.needs_sensor(), Some(Uuid::try_parse(CAL).unwrap()));
    }
}

/// Acts a reader does not act on are no events.
#[test]
fn other_acts_are_not_events() {
    assert_eq!(calibration(1, "calibration.confirm", json!({})), None);
    for (action, object) in [
        ("token.create", "tokens/x"),
        ("token.revoke", "tokens/x"),
        ("sensor_type.put", "sensor-types/A"),
        ("service.configure", "service"),
        ("audit.adopt", "audit"),
    ] {
        assert_eq!(
            LiveEvent::from_entry(&entry(1, action, object, json!({})), Basis::NotRejected),
            None
        );
    }
}

/// A retyped sensor is named by its object; a certificate by its
/// calibration; a nonconformity concerns no one sensor.
#[test]
fn sensors_and_certificates_and_standards() {
    let e = LiveEvent::from_entry(
        &entry(
            2,
            "sensor.retype",
            "sensors/ACC-9",
            json!({"sensor_type": "A"}),
        ),
        Basis::NotRejected,
    )
    .unwrap();
    assert_eq!(
        (e.kind, e.sensor_id.as_deref(), e.calibration_id),
        (EventType::SensorRetyped, Some("ACC-9"), None)
    );
    let st = LiveEvent::from_entry(
        &entry(
            3,
            "sensor.status",
            "sensors/ACC-9",
            json!({"from": "due_soon", "to": "overdue", "due_at": "2026-11-28T00:00:00.000000Z"}),
        ),
        Basis::NotRejected,
    )
    .unwrap();
    assert_eq!(
        (st.kind, st.sensor_id.as_deref(), st.calibration_id),
        (EventType::SensorStatus, Some("ACC-9"), None)
    );
    let c = calibration(4, "certificate.amend", json!({"revision": 2})).unwrap();
    assert_eq!(c.kind, EventType::CertificateAmended);
    let n = LiveEvent::from_entry(
        &entry(5, "standard.nonconformity", "standards/STD-1", json!({})),
        Basis::NotRejected,
    )
    .unwrap();
    assert_eq!(
        (n.kind, n.sensor_id.as_deref(), n.needs_sensor()),
        (EventType::StandardNonconformity, None, None)
    );
}

/// An approval that issued the certificate is also a `certificate.issued`;
/// one that did not is not.
#[test]
fn an_approval_that_issued_a_certificate_is_both() {
    let issuing = calibration(
        6,
        "calibration.approve",
        json!({"from": "submitted", "certificate": {"revision": 1}}),
    )
    .unwrap();
    assert!(issuing.is(EventType::CalibrationApproved));
    assert!(issuing.is(EventType::CertificateIssued));
    let plain = calibration(6, "calibration.approve", json!({"from": "submitted"})).unwrap();
    assert!(!plain.is(EventType::CertificateIssued));
    assert!(!plain.is(EventType::CalibrationRejected));
}

/// A filter selects by sensor and by type; an empty list selects all, and
/// an event of no sensor passes only a filter that names none.
#[test]
fn filters_select_by_sensor_and_type() {
    let mut e = calibration(1, "calibration.submitted", json!({"sensor_id": "A"})).unwrap();
    let all = Filter::default();
    let of_b = Filter {
        sensors: vec!["B".into()],
        types: vec![],
    };
    let of_a_approved = Filter {
        sensors: vec!["A".into(), "B".into()],
        types: vec![EventType::CalibrationApproved],
    };
    let stored = Filter {
        sensors: vec![],
        types: vec![EventType::CalibrationApproved, EventType::CalibrationStored],
    };
    assert!(all.admits(&e));
    assert!(!of_b.admits(&e));
    assert!(!of_a_approved.admits(&e));
    assert!(stored.admits(&e));
    e.sensor_id = None;
    assert!(all.admits(&e) && stored.admits(&e));
    assert!(!of_b.admits(&e));
}

/// Every type's wire name parses back, and is the name it serialises to.
#[test]
fn type_names_round_trip() {
    for t in EventType::ALL {
        assert_eq!(EventType::parse(t.as_str()), Some(t));
        assert_eq!(serde_json::to_value(t).unwrap(), t.as_str());
    }
    assert_eq!(EventType::parse("calibration.deleted"), None);
}

const OTHER: &str = "0193a2b4-0000-7000-8000-0000000000ff";

fn id(s: &str) -> Uuid {
    Uuid::try_parse(s).unwrap()
}

/// Served coefficients change with the calibration served, or with the
/// served one's usability (a hold, a release); the calibration served now
/// is said only when they changed, `null` when none is served.
#[test]
fn served_coefficients_change_with_the_calibration_or_its_hold() {
    let (a, b) = (id(CAL), id(OTHER));
    assert_eq!(
        Served::between(Some((a, true)), Some((a, true))),
        Served::UNCHANGED
    );
    assert_eq!(
        Served::between(Some((a, true)), Some((b, true))),
        Served {
            changed: true,
            calibration_id: Some(b)
        }
    );
    assert_eq!(
        Served::between(Some((a, true)), Some((a, false))),
        Served {
            changed: true,
            calibration_id: Some(a)
        }
    );
    assert_eq!(
        Served::between(Some((a, true)), None),
        Served {
            changed: true,
            calibration_id: None
        }
    );
    // Another calibration's state is not the act's: only the acted one's
    // hold makes its serving unusable.
    assert_eq!(
        Served::serving(Some(b), a, State::UnderReview),
        Some((b, true))
    );
    assert_eq!(
        Served::serving(Some(a), a, State::UnderReview),
        Some((a, false))
    );
    assert_eq!(
        Served::serving(Some(a), a, State::Approved),
        Some((a, true))
    );
    assert_eq!(Served::serving(None, a, State::Approved), None);
    assert_eq!(
        serde_json::to_value(Served::UNCHANGED).unwrap(),
        json!({"changed": false})
    );
    assert_eq!(
        serde_json::to_value(Served::between(Some((a, true)), None)).unwrap(),
        json!({"changed": true, "calibration_id": null})
    );
}

/// The entry records both bases; the event says the service's, once, and
/// not again inside `change`.
#[test]
fn the_event_tells_the_coefficients_on_the_services_basis() {
    let stored = Effect::stored(id(CAL), true);
    let change = json!({"sensor_id": "ACC-1", "coefficients": stored.to_value()});
    let e = |basis| {
        LiveEvent::from_entry(
            &entry(
                9,
                "calibration.submitted",
                &format!("calibrations/{CAL}"),
                change.clone(),
            ),
            basis,
        )
        .unwrap()
    };
    let not_rejected = e(Basis::NotRejected);
    assert_eq!(
        not_rejected.coefficients,
        Some(Served {
            changed: true,
            calibration_id: Some(id(CAL))
        })
    );
    assert!(not_rejected.change.get("coefficients").is_none());
    let json = serde_json::to_value(&not_rejected).unwrap();
    assert_eq!(
        json["coefficients"],
        json!({"changed": true, "calibration_id": CAL})
    );
    // Stored unapproved: nothing served changes with --require-approval.
    assert_eq!(e(Basis::ApprovedOnly).coefficients, Some(Served::UNCHANGED));
    // Not the latest (an older calibration stored late): nothing changes.
    assert_eq!(
        Effect::stored(id(CAL), false),
        Effect {
            not_rejected: Served::UNCHANGED,
            approved_only: Served::UNCHANGED
        }
    );
    // Held as stored: the served one, now unusable.
    assert_eq!(
        Effect::held_on_storing(id(CAL), true).not_rejected,
        Served {
            changed: true,
            calibration_id: Some(id(CAL))
        }
    );
    assert_eq!(
        Effect::held_on_storing(id(CAL), false).not_rejected,
        Served::UNCHANGED
    );
    // An entry from before: no coefficients, and none in the JSON.
    let old = calibration(3, "calibration.submitted", json!({"sensor_id": "ACC-1"})).unwrap();
    assert_eq!(old.coefficients, None);
    assert!(
        serde_json::to_value(&old)
            .unwrap()
            .get("coefficients")
            .is_none()
    );
}
