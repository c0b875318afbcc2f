//! Engine-agnostic conformance tests of the `Store` trait. Every engine runs
//! the same suite; a new engine adds one `#[tokio::test]` that builds it and
//! calls `conformance`.

use std::sync::Arc;

#[path = "common/pg.rs"]
mod pg;

#[path = "store/group_commit.rs"]
mod group_commit;

use accelcal::domain::auth::Role;
use accelcal::domain::sensor_types::SensorType;
use accelcal::domain::status::Status;
use accelcal::domain::timestamp::Timestamp;
use accelcal::domain::tokens::TokenRecord;
use accelcal::store::cache::{CAPACITY, CachedStore, SensorCache, TokenCache};
use accelcal::store::{
    Claim, HistoryQuery, IdempotencyKey, NewCalibration, SensorQuery, Store, StoreError, Stored,
    postgres::PostgresStore, sqlite::SqliteStore,
};
use accelcal_core::decision::{Limit, Rule, Verdict};
use accelcal_core::{Model, Term, TermMap};
use bytes::Bytes;
use uuid::Uuid;

fn t(s: &str) -> Timestamp {
    Timestamp::parse(s).unwrap()
}

fn calibration(sensor: &str, performed_at: &str) -> NewCalibration {
    let id = Uuid::now_v7();
    NewCalibration {
        id,
        sensor_id: sensor.into(),
        station_id: Some("LAB-1".into()),
        performed_at: t(performed_at),
        received_at: t("2026-11-22T00:00:00Z"),
        unit: "mA".into(),
        model: Model::new(vec![Term::K0, Term::Ki]).unwrap(),
        runs: 4,
        coefficients: TermMap(vec![(Term::K0, 0.001), (Term::Ki, -1.2)]),
        std_errors: TermMap(vec![(Term::K0, 1e-6), (Term::Ki, 2e-6)]),
        result: Bytes::from(format!(r#"{{"id":"{id}"}}"#)),
        submission: Bytes::from_static(b"{\"raw\": true}"),
        content_type: "application/json".into(),
        submitted_by: "tester".into(),
        sensor_type: None,
        assigns_type: false,
        verdict: None,
        due_at: None,
        expanded: Some(TermMap(vec![(Term::K0, 2e-6), (Term::Ki, 4e-6)])),
    }
}

fn now() -> Timestamp {
    t("2026-11-22T00:00:00Z")
}

fn all_sensors(after: Option<String>, limit: usize) -> SensorQuery {
    SensorQuery {
        after,
        status: None,
        search: None,
        now: now(),
        limit,
    }
}

fn key(k: &str, body: u8) -> IdempotencyKey {
    IdempotencyKey {
        principal: "p-1".into(),
        key: k.into(),
        request_hash: [body; 32],
        holder: Uuid::from_u128(u128::from(body)),
    }
}

async fn calibrations_and_sensors(s: &dyn Store) {
    let a = calibration("S-1", "2026-01-01T00:00:00Z");
    let b = calibration("S-1", "2026-03-01T00:00:00Z");
    let c = calibration("S-1", "2026-02-01T00:00:00Z");
    let d = calibration("S-2", "2026-01-01T00:00:00Z");
    for n in [&a, &b, &c, &d] {
        assert_eq!(
            s.insert_calibration(n.clone(), None).await.unwrap(),
            Stored::New
        );
    }
    assert_eq!(s.calibration_result(a.id).await.unwrap().unwrap(), a.result);
    let sub = s.submission(a.id).await.unwrap().unwrap();
    assert_eq!(
        (sub.content_type.as_str(), &sub.body[..]),
        ("application/json", &a.submission[..])
    );
    assert!(
        s.calibration_result(Uuid::now_v7())
            .await
            .unwrap()
            .is_none()
    );

    let s1 = s.sensor("S-1".into(), now()).await.unwrap().unwrap();
    assert_eq!(s1.calibration_count, 3);
    assert_eq!(
        s1.latest.id, b.id,
        "latest is by performed_at, not by arrival"
    );
    assert_eq!(s1.first_performed_at, t("2026-01-01T00:00:00Z"));
    assert_eq!(s1.latest.coefficients, b.coefficients);
    assert_eq!(s1.latest.std_errors, b.std_errors);
    assert_eq!(s1.latest.model, b.model);
    assert_eq!(s1.latest.performed_at, b.performed_at);
    assert!(s.sensor("S-9".into(), now()).await.unwrap().is_none());

    let page = s.sensors(all_sensors(None, 1)).await.unwrap();
    assert_eq!(
        page.iter()
            .map(|x| x.sensor_id.as_str())
            .collect::<Vec<_>>(),
        ["S-1"]
    );
    let page = s
        .sensors(all_sensors(Some("S-1".into()), 10))
        .await
        .unwrap();
    assert_eq!(
        page.iter()
            .map(|x| x.sensor_id.as_str())
            .collect::<Vec<_>>(),
        ["S-2"]
    );

    let all = |q: HistoryQuery| async move {
        s.history("S-1".into(), q)
            .await
            .unwrap()
            .into_iter()
            .map(|c| c.id)
            .collect::<Vec<_>>()
    };
    let q = |before, from: Option<&str>, to: Option<&str>| HistoryQuery {
        from: from.map(t),
        to: to.map(t),
        before,
        limit: 10,
    };
    assert_eq!(all(q(None, None, None)).await, [b.id, c.id, a.id]);
    assert_eq!(all(q(Some(b.id), None, None)).await, [c.id, a.id]);
    assert_eq!(
        all(q(
            None,
            Some("2026-01-15T00:00:00Z"),
            Some("2026-02-01T00:00:00Z")
        ))
        .await,
        [c.id]
    );
    assert_eq!(
        s.calibration_summary(d.id)
            .await
            .unwrap()
            .unwrap()
            .sensor_id,
        "S-2"
    );
}

async fn tokens(s: &dyn Store) {
    assert!(!s.has_admin_token().await.unwrap());
    let record = TokenRecord {
        id: Uuid::now_v7(),
        secret_hash: vec![7; 32],
        role: Role::Admin,
        station_id: None,
        label: Some("ops".into()),
        created_at: t("2026-11-22T00:00:00Z"),
        revoked_at: None,
    };
    s.insert_token(record.clone()).await.unwrap();
    assert_eq!(s.token(record.id).await.unwrap().unwrap(), record);
    assert!(s.has_admin_token().await.unwrap());
    assert_eq!(s.tokens().await.unwrap(), vec![record.clone()]);
    assert!(
        s.revoke_token(record.id, t("2026-11-22T01:00:00Z"))
            .await
            .unwrap()
    );
    assert!(
        !s.revoke_token(record.id, t("2026-11-22T02:00:00Z"))
            .await
            .unwrap(),
        "revoked once only"
    );
    assert_eq!(
        s.token(record.id).await.unwrap().unwrap().revoked_at,
        Some(t("2026-11-22T01:00:00Z"))
    );
    assert!(!s.has_admin_token().await.unwrap());
}

async fn idempotency(s: &dyn Store) {
    let now = t("2026-11-22T00:00:00Z");
    let lease = now.plus_seconds(90);
    // A new key is fresh, then in flight for the same request, a mismatch for another.
    assert_eq!(
        s.claim_key(key("k", 1), now, lease).await.unwrap(),
        Claim::Fresh
    );
    assert_eq!(
        s.claim_key(key("k", 1), now, lease).await.unwrap(),
        Claim::InFlight
    );
    assert_eq!(
        s.claim_key(key("k", 2), now, lease).await.unwrap(),
        Claim::Mismatch
    );
    // An expired lease may be taken over.
    let later = now.plus_seconds(120);
    assert_eq!(
        s.claim_key(key("k", 1), later, later.plus_seconds(90))
            .await
            .unwrap(),
        Claim::Fresh
    );
    // Completing the key records it; retries replay it.
    let c = calibration("S-K", "2026-01-01T00:00:00Z");
    assert_eq!(
        s.insert_calibration(c.clone(), Some(key("k", 1)))
            .await
            .unwrap(),
        Stored::New
    );
    assert_eq!(
        s.claim_key(key("k", 1), later, later).await.unwrap(),
        Claim::Done(c.id)
    );
    // A second completion of the same key stores nothing and names the first.
    let twin = calibration("S-K", "2026-01-01T00:00:00Z");
    assert_eq!(
        s.insert_calibration(twin.clone(), Some(key("k", 1)))
            .await
            .unwrap(),
        Stored::Existing(c.id)
    );
    assert!(s.calibration_result(twin.id).await.unwrap().is_none());
    assert_eq!(
        s.sensor("S-K".into(), now)
            .await
            .unwrap()
            .unwrap()
            .calibration_count,
        1
    );
    // A released key is forgotten; a completed one is not.
    assert_eq!(
        s.claim_key(key("r", 3), now, lease).await.unwrap(),
        Claim::Fresh
    );
    s.release_key(key("r", 3)).await.unwrap();
    assert_eq!(
        s.claim_key(key("r", 4), now, lease).await.unwrap(),
        Claim::Fresh
    );
    s.release_key(key("k", 1)).await.unwrap();
    assert_eq!(
        s.claim_key(key("k", 1), later, later).await.unwrap(),
        Claim::Done(c.id)
    );
    // A request whose lease expired and was taken over cannot free the key:
    // it belongs to the request that holds it now.
    let first = IdempotencyKey {
        holder: Uuid::from_u128(7),
        ..key("t", 5)
    };
    let second = IdempotencyKey {
        holder: Uuid::from_u128(8),
        ..key("t", 5)
    };
    assert_eq!(
        s.claim_key(first.clone(), now, lease).await.unwrap(),
        Claim::Fresh
    );
    assert_eq!(
        s.claim_key(second.clone(), later, later.plus_seconds(90))
            .await
            .unwrap(),
        Claim::Fresh
    );
    s.release_key(first).await.unwrap();
    assert_eq!(
        s.claim_key(key("t", 5), later, later.plus_seconds(90))
            .await
            .unwrap(),
        Claim::InFlight,
        "the live lease survives a late release by its former holder"
    );
    s.release_key(second).await.unwrap();
    assert_eq!(
        s.claim_key(key("t", 5), later, later.plus_seconds(90))
            .await
            .unwrap(),
        Claim::Fresh,
        "its holder may release it"
    );
    // Keys are per principal.
    let other = IdempotencyKey {
        principal: "p-2".into(),
        ..key("k", 9)
    };
    assert_eq!(s.claim_key(other, now, lease).await.unwrap(), Claim::Fresh);
    // Keys are kept 48 hours, then forgotten.
    let day = now.plus_seconds(24 * 3600);
    assert_eq!(
        s.claim_key(key("k", 1), day, day).await.unwrap(),
        Claim::Done(c.id)
    );
    let gone = now.plus_seconds(49 * 3600);
    assert_eq!(
        s.claim_key(key("k", 1), gone, gone.plus_seconds(90))
            .await
            .unwrap(),
        Claim::Fresh
    );
}

/// Nothing non-finite is ever stored: a record holding NaN or infinity is
/// refused before anything is written, and the sensor is left untouched.
async fn non_finite_values_are_refused(s: &dyn Store) {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut c = calibration("S-NAN", "2026-01-01T00:00:00Z");
        c.coefficients = TermMap(vec![(Term::K0, bad), (Term::Ki, -1.2)]);
        let err = s.insert_calibration(c.clone(), None).await.unwrap_err();
        assert!(matches!(err, StoreError::Refused(_)), "{err:?}");
        let mut c = calibration("S-NAN", "2026-01-01T00:00:00Z");
        c.std_errors = TermMap(vec![(Term::K0, 1e-6), (Term::Ki, bad)]);
        assert!(s.insert_calibration(c.clone(), None).await.is_err());
        assert!(s.calibration_result(c.id).await.unwrap().is_none());
        let mut c = calibration("S-NAN", "2026-01-01T00:00:00Z");
        c.expanded = Some(TermMap(vec![(Term::K0, bad), (Term::Ki, 1e-6)]));
        let err = s.insert_calibration(c.clone(), None).await.unwrap_err();
        assert!(matches!(err, StoreError::Refused(_)), "{err:?}");
    }
    assert!(s.sensor("S-NAN".into(), now()).await.unwrap().is_none());
}

/// Every stored number comes back bit for bit: what a control system loads
/// is exactly what the calibration computed (found by the soak: serde_json
/// without `float_roundtrip` can parse a shortest representation 1 ulp off).
async fn numbers_round_trip_exactly(s: &dyn Store) {
    let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = || {
        // xorshift64*: deterministic, spread over magnitudes and mantissas.
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        let bits = state.wrapping_mul(0x2545_f491_4f6c_dd1d);
        let x = f64::from_bits((bits >> 12) | 0x3ff0_0000_0000_0000) - 1.0;
        x * 10f64.powi((bits % 40) as i32 - 20) * if bits & 1 == 0 { 1.0 } else { -1.0 }
    };
    for _ in 0..200 {
        let mut c = calibration("S-BITS", "2026-01-01T00:00:00Z");
        c.coefficients = TermMap(vec![(Term::K0, next()), (Term::Ki, next())]);
        c.std_errors = TermMap(vec![(Term::K0, next().abs()), (Term::Ki, next().abs())]);
        s.insert_calibration(c.clone(), None).await.unwrap();
        let back = s.calibration_summary(c.id).await.unwrap().unwrap();
        for ((_, a), (_, b)) in back.coefficients.iter().zip(c.coefficients.iter()) {
            assert_eq!(a.to_bits(), b.to_bits(), "{a:e} came back for {b:e}");
        }
        for ((_, a), (_, b)) in back.std_errors.iter().zip(c.std_errors.iter()) {
            assert_eq!(a.to_bits(), b.to_bits(), "{a:e} came back for {b:e}");
        }
        assert_eq!(back.expanded, c.expanded);
    }
}

/// Sensors found by a part of their id, any case, with the other filters.
async fn search(s: &dyn Store) {
    for id in ["FIND-acc-001", "FIND-ACC-002", "FIND-gyro-1"] {
        s.insert_calibration(calibration(id, "2026-01-01T00:00:00Z"), None)
            .await
            .unwrap();
    }
    let found = |text: &str| {
        let q = SensorQuery {
            search: Some(text.into()),
            ..all_sensors(None, 50)
        };
        async move {
            s.sensors(q)
                .await
                .unwrap()
                .into_iter()
                .map(|x| x.sensor_id)
                .collect::<Vec<_>>()
        }
    };
    assert_eq!(found("acc-").await, ["FIND-ACC-002", "FIND-acc-001"]);
    assert_eq!(found("GYRO").await, ["FIND-gyro-1"]);
    assert_eq!(found("find-").await.len(), 3);
    assert!(
        found("%").await.is_empty(),
        "no wildcard: `%` is a character"
    );
    assert!(
        found("_").await.is_empty(),
        "no wildcard: `_` is a character"
    );
    let after = SensorQuery {
        search: Some("acc".into()),
        ..all_sensors(Some("FIND-ACC-002".into()), 50)
    };
    let page: Vec<String> = s
        .sensors(after)
        .await
        .unwrap()
        .into_iter()
        .map(|x| x.sensor_id)
        .collect();
    assert_eq!(page, ["FIND-acc-001"]);
}

/// Web sessions: stored by the hash of their id, read back whole, ended
/// once; expired ones forgotten when a new one opens.
async fn sessions(s: &dyn Store) {
    use accelcal::domain::session::open;
    let (old, _) = open("p-1".into(), [1; 32], t("2026-01-01T00:00:00Z"), 60).unwrap();
    s.insert_session(old.clone()).await.unwrap();
    assert_eq!(s.session(old.id_hash).await.unwrap(), Some(old.clone()));
    let (new, _) = open("p-2".into(), [2; 32], t("2026-01-01T00:01:00Z"), 60).unwrap();
    s.insert_session(new.clone()).await.unwrap();
    assert_eq!(
        s.session(old.id_hash).await.unwrap(),
        None,
        "expired by the new one's start"
    );
    assert_eq!(s.session(new.id_hash).await.unwrap(), Some(new.clone()));
    assert!(s.delete_session(new.id_hash).await.unwrap());
    assert!(!s.delete_session(new.id_hash).await.unwrap());
    assert_eq!(s.session(new.id_hash).await.unwrap(), None);
}

fn sensor_type(id: &str, interval_days: u32) -> SensorType {
    SensorType {
        type_id: id.into(),
        label: Some("nav".into()),
        limits: TermMap(vec![(
            Term::K0,
            Limit {
                min: Some(-1e-3),
                max: Some(1e-3),
            },
        )]),
        decision_rule: Rule::Guarded,
        coverage_factor: 2.0,
        interval_days,
        updated_at: now(),
    }
}

/// Sensor types, their assignment, and what typed calibrations leave on
/// their sensor: the latest verdict and due date, from which the status is
/// computed — by the store in SQL, to filter, and by the domain's rule,
/// which must agree.
async fn types_and_statuses(s: &dyn Store) {
    assert!(
        s.put_sensor_type(sensor_type("NAV", 365)).await.unwrap(),
        "created"
    );
    assert!(
        !s.put_sensor_type(sensor_type("NAV", 180)).await.unwrap(),
        "replaced"
    );
    assert_eq!(
        s.sensor_type("NAV".into())
            .await
            .unwrap()
            .unwrap()
            .interval_days,
        180
    );
    s.put_sensor_type(sensor_type("AAA", 30)).await.unwrap();
    let ids: Vec<String> = s
        .sensor_types()
        .await
        .unwrap()
        .into_iter()
        .map(|t| t.type_id)
        .collect();
    assert_eq!(ids, ["AAA", "NAV"]);
    assert!(s.sensor_type("NONE".into()).await.unwrap().is_none());

    // One sensor per status, at now() = 2026-11-22.
    let typed = |sensor: &str, at: &str, verdict: Verdict, due: &str| {
        let mut c = calibration(sensor, at);
        c.sensor_type = Some("NAV".into());
        c.assigns_type = true;
        c.verdict = Some(verdict);
        c.due_at = Some(t(due));
        c
    };
    for c in [
        typed(
            "ST-FAILED",
            "2026-10-01T00:00:00Z",
            Verdict::Fail,
            "2027-04-01T00:00:00Z",
        ),
        typed(
            "ST-OVERDUE",
            "2025-01-01T00:00:00Z",
            Verdict::Pass,
            "2025-07-01T00:00:00Z",
        ),
        typed(
            "ST-SOON",
            "2026-06-01T00:00:00Z",
            Verdict::Conditional,
            "2026-12-01T00:00:00Z",
        ),
        typed(
            "ST-OK",
            "2026-10-01T00:00:00Z",
            Verdict::Pass,
            "2027-04-01T00:00:00Z",
        ),
        calibration("ST-UNKNOWN", "2026-10-01T00:00:00Z"),
    ] {
        s.insert_calibration(c, None).await.unwrap();
    }
    // An older calibration does not replace the latest verdict.
    s.insert_calibration(
        typed(
            "ST-OK",
            "2020-01-01T00:00:00Z",
            Verdict::Fail,
            "2020-07-01T00:00:00Z",
        ),
        None,
    )
    .await
    .unwrap();
    let ok = s.sensor("ST-OK".into(), now()).await.unwrap().unwrap();
    assert_eq!(
        (ok.status, ok.latest_verdict, ok.sensor_type.as_deref()),
        (Status::Ok, Some(Verdict::Pass), Some("NAV"))
    );
    assert_eq!(ok.due_at, Some(t("2027-04-01T00:00:00Z")));
    for status in Status::ALL {
        let page = s
            .sensors(SensorQuery {
                after: Some("ST-".into()),
                status: Some(status),
                search: None,
                now: now(),
                limit: 50,
            })
            .await
            .unwrap();
        let names: Vec<&str> = page
            .iter()
            .map(|x| x.sensor_id.as_str())
            .filter(|n| n.starts_with("ST-"))
            .collect();
        let want = match status {
            Status::Failed => "ST-FAILED",
            Status::Overdue => "ST-OVERDUE",
            Status::DueSoon => "ST-SOON",
            Status::Ok => "ST-OK",
            Status::Unknown => "ST-UNKNOWN",
        };
        assert_eq!(names, [want], "{status:?}");
        for x in &page {
            let rule = Status::of(x.latest_verdict == Some(Verdict::Fail), x.due_at, now());
            assert_eq!(
                x.status, rule,
                "the store and the domain's rule agree for {}",
                x.sensor_id
            );
        }
    }
    // Assigning a type: only to an existing sensor; it applies from then on.
    assert!(
        s.assign_sensor_type("ST-UNKNOWN".into(), "AAA".into())
            .await
            .unwrap()
    );
    assert!(
        !s.assign_sensor_type("NO-SUCH".into(), "AAA".into())
            .await
            .unwrap()
    );
    let unknown = s.sensor("ST-UNKNOWN".into(), now()).await.unwrap().unwrap();
    assert_eq!(
        (unknown.sensor_type.as_deref(), unknown.status),
        (Some("AAA"), Status::Unknown)
    );
    // A calibration that does not name a type keeps the sensor's.
    s.insert_calibration(calibration("ST-UNKNOWN", "2026-11-01T00:00:00Z"), None)
        .await
        .unwrap();
    let kept = s.sensor("ST-UNKNOWN".into(), now()).await.unwrap().unwrap();
    assert_eq!(kept.sensor_type.as_deref(), Some("AAA"));
}

/// The series (oldest first, within the window) and the previous
/// calibration (strictly earlier).
async fn series_and_previous(s: &dyn Store) {
    let a = calibration("SER", "2026-01-01T00:00:00Z");
    let b = calibration("SER", "2026-02-01T00:00:00Z");
    let c = calibration("SER", "2026-03-01T00:00:00Z");
    for x in [&c, &a, &b] {
        s.insert_calibration(x.clone(), None).await.unwrap();
    }
    let ids = |v: accelcal::store::Series| {
        (
            v.items.into_iter().map(|x| x.id).collect::<Vec<_>>(),
            v.in_window,
        )
    };
    assert_eq!(
        ids(s.series("SER".into(), None, None, 10).await.unwrap()),
        (vec![a.id, b.id, c.id], 3)
    );
    assert_eq!(
        ids(s
            .series(
                "SER".into(),
                Some(t("2026-01-15T00:00:00Z")),
                Some(t("2026-03-01T00:00:00Z")),
                10
            )
            .await
            .unwrap()),
        (vec![b.id, c.id], 2)
    );
    // The limit keeps the latest, oldest first, and counts the window.
    assert_eq!(
        ids(s.series("SER".into(), None, None, 2).await.unwrap()),
        (vec![b.id, c.id], 3)
    );
    assert_eq!(
        ids(s.series("NONE".into(), None, None, 10).await.unwrap()),
        (vec![], 0)
    );
    let prev = |at: &'static str| async move {
        s.previous_calibration("SER".into(), t(at))
            .await
            .unwrap()
            .map(|x| x.id)
    };
    assert_eq!(
        prev("2026-03-01T00:00:00Z").await,
        Some(b.id),
        "strictly before"
    );
    assert_eq!(prev("2026-03-02T00:00:00Z").await, Some(c.id));
    assert_eq!(prev("2026-01-01T00:00:00Z").await, None);
    // The same answers, whole, once the sensor's summary was read (behind
    // the sensor cache, that read fills it, and the cache answers what it
    // can).
    let whole = |at: &'static str| async move {
        s.previous_calibration("SER".into(), t(at)).await.unwrap()
    };
    let dates = [
        "2026-01-01T00:00:00Z",
        "2026-02-15T00:00:00Z",
        "2026-03-01T00:00:00Z",
        "2026-03-01T00:00:00.000001Z",
        "2027-01-01T00:00:00Z",
    ];
    let mut before = Vec::new();
    for at in dates {
        before.push(whole(at).await);
    }
    s.sensor("SER".into(), now()).await.unwrap().unwrap();
    for (at, expected) in dates.into_iter().zip(before) {
        assert_eq!(whole(at).await, expected, "previous before {at}");
    }
    assert_eq!(
        whole("2027-01-01T00:00:00Z").await.map(|x| x.id),
        Some(c.id)
    );

    // The latest calibration's id: the sensor's `latest`, before and after
    // a newer write (behind the cache, a hit until that write drops it).
    let latest = || async { s.latest_calibration_id("SER".into()).await.unwrap() };
    assert_eq!(latest().await, Some(c.id));
    assert_eq!(s.latest_calibration_id("NONE".into()).await.unwrap(), None);
    let d = calibration("SER", "2026-04-01T00:00:00Z");
    s.insert_calibration(d.clone(), None).await.unwrap();
    assert_eq!(latest().await, Some(d.id));
    let older = calibration("SER", "2025-12-01T00:00:00Z");
    let older_id = older.id;
    s.insert_calibration(older, None).await.unwrap();
    assert_eq!(latest().await, Some(d.id));
    assert_eq!(
        latest().await,
        s.sensor("SER".into(), now())
            .await
            .unwrap()
            .map(|x| x.latest.id)
    );

    // A history page's ids are the ids of its summaries, in order.
    let page = |limit: usize| HistoryQuery {
        limit,
        ..HistoryQuery::default()
    };
    let queries = [
        page(10),
        page(2),
        HistoryQuery {
            before: Some(c.id),
            ..page(10)
        },
        HistoryQuery {
            from: Some(t("2026-01-15T00:00:00Z")),
            to: Some(t("2026-03-01T00:00:00Z")),
            ..page(10)
        },
    ];
    for q in queries {
        let whole: Vec<_> = s
            .history("SER".into(), q.clone())
            .await
            .unwrap()
            .into_iter()
            .map(|x| x.id)
            .collect();
        assert!(!whole.is_empty(), "{q:?}");
        assert_eq!(
            s.history_ids("SER".into(), q.clone()).await.unwrap(),
            whole,
            "{q:?}"
        );
    }
    assert_eq!(
        s.history_ids("SER".into(), page(10)).await.unwrap(),
        [d.id, c.id, b.id, a.id, older_id]
    );
}

/// The whole suite, on a fresh, empty store.
async fn conformance(s: Arc<dyn Store>) {
    s.ping().await.unwrap();
    calibrations_and_sensors(s.as_ref()).await;
    tokens(s.as_ref()).await;
    idempotency(s.as_ref()).await;
    non_finite_values_are_refused(s.as_ref()).await;
    numbers_round_trip_exactly(s.as_ref()).await;
    types_and_statuses(s.as_ref()).await;
    series_and_previous(s.as_ref()).await;
    search(s.as_ref()).await;
    sessions(s.as_ref()).await;
    s.close().await;
}

/// Two handles on one database — two replicas — racing: of two claims of
/// one key exactly one wins; concurrent inserts for one sensor lose no
/// count and agree on the latest.
async fn two_handles(a: Arc<dyn Store>, b: Arc<dyn Store>) {
    let now = t("2026-11-22T00:00:00Z");
    for round in 0..20 {
        let k = key(&format!("race-{round}"), 1);
        let (x, y) = tokio::join!(
            a.claim_key(
                IdempotencyKey {
                    holder: Uuid::from_u128(1),
                    ..k.clone()
                },
                now,
                now.plus_seconds(90)
            ),
            b.claim_key(
                IdempotencyKey {
                    holder: Uuid::from_u128(2),
                    ..k.clone()
                },
                now,
                now.plus_seconds(90)
            ),
        );
        let mut got = [x.unwrap(), y.unwrap()];
        got.sort_by_key(|c| matches!(c, Claim::InFlight));
        assert_eq!(got, [Claim::Fresh, Claim::InFlight], "round {round}");
        // Both complete the key at once: one stores, the other names it.
        let (c1, c2) = (
            calibration(&format!("RACE-{round}"), "2026-01-01T00:00:00Z"),
            calibration(&format!("RACE-{round}"), "2026-01-02T00:00:00Z"),
        );
        let (r1, r2) = tokio::join!(
            a.insert_calibration(c1.clone(), Some(k.clone())),
            b.insert_calibration(c2.clone(), Some(k.clone())),
        );
        let (r1, r2) = (r1.unwrap(), r2.unwrap());
        let stored: Vec<Uuid> = [(&r1, c1.id), (&r2, c2.id)]
            .iter()
            .filter(|(r, _)| **r == Stored::New)
            .map(|(_, id)| *id)
            .collect();
        assert_eq!(stored.len(), 1, "round {round}: {r1:?} {r2:?}");
        for r in [r1, r2] {
            if let Stored::Existing(id) = r {
                assert_eq!(id, stored[0]);
            }
        }
        let sensor = a
            .sensor(format!("RACE-{round}"), now)
            .await
            .unwrap()
            .unwrap();
        assert_eq!((sensor.calibration_count, sensor.latest.id), (1, stored[0]));
    }
    // Forty inserts for one sensor through both handles: every one counted.
    let all: Vec<NewCalibration> = (0..40)
        .map(|i| calibration("HOT", &format!("2026-01-01T00:00:{i:02}Z")))
        .collect();
    let mut handles = Vec::new();
    for (i, c) in all.iter().cloned().enumerate() {
        let s = if i % 2 == 0 { a.clone() } else { b.clone() };
        handles.push(tokio::spawn(
            async move { s.insert_calibration(c, None).await },
        ));
    }
    for h in handles {
        assert_eq!(h.await.unwrap().unwrap(), Stored::New);
    }
    let hot = b.sensor("HOT".into(), now).await.unwrap().unwrap();
    assert_eq!(hot.calibration_count, 40);
    assert_eq!(
        hot.latest.id,
        all.last().unwrap().id,
        "the latest performed_at wins"
    );
    assert_eq!(hot.first_performed_at, t("2026-01-01T00:00:00Z"));
}

#[tokio::test]
async fn sqlite_conforms() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(dir.path().join("conformance.db")).unwrap();
    conformance(Arc::new(store)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn sqlite_handles_agree() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two.db");
    let a = SqliteStore::open(&path).unwrap();
    let b = SqliteStore::open(&path).unwrap();
    two_handles(Arc::new(a), Arc::new(b)).await;
}

/// Many reads at once share the pool's reader connections: none is opened
/// beyond them (an open parses the whole schema; churning connections under
/// load was the submit path's largest cost after the disk).
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn sqlite_concurrent_reads_reuse_the_pool() {
    let dir = tempfile::tempdir().unwrap();
    let store = Arc::new(SqliteStore::open(dir.path().join("readers.db")).unwrap());
    store
        .insert_calibration(calibration("R-1", "2026-01-01T00:00:00Z"), None)
        .await
        .unwrap();
    let before = store.connections_opened();
    for _ in 0..4 {
        let reads: Vec<_> = (0..64)
            .map(|_| {
                let store = store.clone();
                tokio::spawn(async move {
                    store
                        .previous_calibration("R-1".into(), t("2026-06-01T00:00:00Z"))
                        .await
                })
            })
            .collect();
        for r in reads {
            assert!(r.await.unwrap().unwrap().is_some());
        }
    }
    let opened = store.connections_opened();
    assert!(
        opened <= accelcal::store::sqlite::READERS + 1,
        "{opened} connections opened for 256 reads ({before} before them)"
    );
}

#[tokio::test]
async fn postgres_conforms() {
    let db = pg::TestDb::create().await;
    let store = PostgresStore::open(&db.url).await.unwrap();
    conformance(Arc::new(store)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replicas_agree() {
    let db = pg::TestDb::create().await;
    let (a, b) = tokio::join!(PostgresStore::open(&db.url), PostgresStore::open(&db.url));
    two_handles(Arc::new(a.unwrap()), Arc::new(b.unwrap())).await;
}

/// Replicas starting at once migrate once: the advisory lock.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replicas_starting_together_migrate_once() {
    let db = pg::TestDb::create().await;
    let opens: Vec<_> = (0..6)
        .map(|_| {
            let url = db.url.clone();
            tokio::spawn(async move { PostgresStore::open(&url).await.map(|_| ()) })
        })
        .collect();
    for o in opens {
        o.await.unwrap().unwrap();
    }
    let c = db.client().await;
    let versions: Vec<i32> = c
        .query(
            "SELECT version FROM accelcal_migrations ORDER BY version",
            &[],
        )
        .await
        .unwrap()
        .iter()
        .map(|r| r.get(0))
        .collect();
    assert_eq!(versions, [1, 2, 3, 4, 5]);
    // Version 4: tokens' changes are notified.
    let triggers = c
        .query(
            "SELECT 1 FROM pg_trigger WHERE tgname = 'tokens_notify' AND NOT tgisinternal",
            &[],
        )
        .await
        .unwrap();
    assert_eq!(triggers.len(), 1, "version 4's trigger");
    // Version 3: result documents and submissions compressed with lz4 (this
    // server, Debian's, is built with it).
    let compression: Vec<(String, i8)> = c
        .query(
            "SELECT attname::text, attcompression FROM pg_attribute \
             WHERE attrelid = 'calibrations'::regclass AND attname IN ('result', 'submission') \
             ORDER BY attname",
            &[],
        )
        .await
        .unwrap()
        .iter()
        .map(|r| (r.get(0), r.get(1)))
        .collect();
    assert_eq!(
        compression,
        [
            ("result".to_owned(), b'l' as i8),
            ("submission".to_owned(), b'l' as i8)
        ]
    );
}

/// Every pooled connection commits durably, whatever the server's default.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_every_connection_commits_durably() {
    let db = pg::TestDb::create().await;
    db.client()
        .await
        .batch_execute(&format!(
            "ALTER DATABASE {} SET synchronous_commit = off",
            db.name
        ))
        .await
        .unwrap();
    let store = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let checks: Vec<_> = (0..32)
        .map(|_| {
            let s = store.clone();
            tokio::spawn(async move { s.session_setting("synchronous_commit").await.unwrap() })
        })
        .collect();
    for c in checks {
        assert_eq!(c.await.unwrap(), "on");
    }
    assert_eq!(
        store.session_setting("application_name").await.unwrap(),
        "accelcal"
    );
}

/// TLS as the URL asks: `sslmode=require` encrypts (the test server has
/// TLS on), `disable` does not, and a certificate that does not chain to
/// the given `sslrootcert` is refused.
#[tokio::test]
async fn postgres_tls_follows_the_url() {
    let db = pg::TestDb::create().await;
    let with = |params: &str| {
        let sep = if db.url.contains('?') { '&' } else { '?' };
        format!("{}{sep}{params}", db.url)
    };
    let required = PostgresStore::open(&with("sslmode=require")).await.unwrap();
    assert!(
        required.encrypted().await.unwrap(),
        "sslmode=require must encrypt"
    );
    let plain = PostgresStore::open(&with("sslmode=disable")).await.unwrap();
    assert!(!plain.encrypted().await.unwrap());
    // A CA that signed nothing here: the server's certificate cannot chain to it.
    let dir = tempfile::tempdir().unwrap();
    let ca = dir.path().join("other-ca.pem");
    std::fs::write(&ca, OTHER_CA).unwrap();
    let refused = PostgresStore::open(&with(&format!(
        "sslmode=require&sslrootcert={}",
        ca.display()
    )))
    .await;
    let Err(StoreError::Unavailable(why)) = refused else {
        panic!("an unverifiable server must be refused");
    };
    let why = format!("{why:?}");
    assert!(
        why.contains("UnknownIssuer"),
        "refused for its certificate: {why}"
    );
}

/// A self-signed CA certificate that signed nothing the test server holds.
const OTHER_CA: &str = include_str!("common/other-ca.pem");

/// The PostgreSQL schema itself refuses a non-finite (`null`) number and
/// any change to a stored calibration.
#[tokio::test]
async fn postgres_schema_refuses_non_finite_numbers_and_changes() {
    let db = pg::TestDb::create().await;
    let store = PostgresStore::open(&db.url).await.unwrap();
    let c = calibration("S-1", "2026-01-01T00:00:00Z");
    store.insert_calibration(c.clone(), None).await.unwrap();
    let client = db.client().await;
    let copy = |coefficients: &'static str, expanded: &'static str| {
        let client = &client;
        let id = c.id;
        async move {
            client
                .execute(
                    "INSERT INTO calibrations SELECT $1, sensor_id, station_id, performed_at, received_at, \
                     unit, model, runs, $2::text::json, std_errors, $3::text::json, result, submission, \
                     content_type, submitted_by, sensor_type, verdict, due_at FROM calibrations WHERE id = $4",
                    &[&Uuid::now_v7(), &coefficients, &expanded, &id],
                )
                .await
        }
    };
    let good = r#"{"k0":1e-6,"ki":2e-6}"#;
    let refused = copy(r#"{"k0":null,"ki":-1.2}"#, good).await.unwrap_err();
    assert!(format!("{refused:?}").contains("finite"), "{refused:?}");
    assert!(copy(r#"{"k0":"1","ki":-1.2}"#, good).await.is_err());
    let refused = copy(r#"{"k0":0.5,"ki":-1.2}"#, r#"{"k0":null}"#)
        .await
        .unwrap_err();
    assert!(
        format!("{refused:?}").contains("expanded uncertainties"),
        "{refused:?}"
    );
    copy(r#"{"k0":0.5,"ki":-1.2}"#, good).await.unwrap();
    let changed = client
        .execute("UPDATE calibrations SET unit = 'x' WHERE id = $1", &[&c.id])
        .await
        .unwrap_err();
    assert!(
        format!("{changed:?}").contains("never changes"),
        "{changed:?}"
    );
}

#[tokio::test]
async fn sqlite_frees_leases_of_a_crashed_process_at_open() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("leases.db");
    let now = Timestamp::now();
    let first = SqliteStore::open(&path).unwrap();
    assert_eq!(
        first
            .claim_key(key("k", 1), now, now.plus_seconds(3600))
            .await
            .unwrap(),
        Claim::Fresh
    );
    drop(first);
    let second = SqliteStore::open(&path).unwrap();
    assert_eq!(
        second
            .claim_key(key("k", 1), now, now.plus_seconds(3600))
            .await
            .unwrap(),
        Claim::Fresh
    );
}

/// The SQLite schema itself refuses what the service would never write: a
/// non-finite (`null`) coefficient, and any change to a stored calibration.
#[tokio::test]
async fn sqlite_schema_refuses_non_finite_numbers_and_changes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("schema.db");
    let store = SqliteStore::open(&path).unwrap();
    let c = calibration("S-1", "2026-01-01T00:00:00Z");
    store.insert_calibration(c.clone(), None).await.unwrap();
    store.close().await;
    let db = rusqlite::Connection::open(&path).unwrap();
    let copy_with = |coefficients: &str, expanded: &str| {
        db.execute(
            "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, \
             unit, model, runs, coefficients, std_errors, result, submission, content_type, \
             submitted_by, sensor_type, verdict, due_at, expanded) \
             SELECT ?1, sensor_id, station_id, performed_at, received_at, \
             unit, model, runs, ?2, std_errors, result, submission, content_type, submitted_by, \
             sensor_type, verdict, due_at, ?3 FROM calibrations WHERE id = ?4",
            rusqlite::params![
                Uuid::now_v7().to_string(),
                coefficients,
                expanded,
                c.id.to_string()
            ],
        )
    };
    let good = r#"{"k0":1e-6,"ki":2e-6}"#;
    let copy = |coefficients: &str| copy_with(coefficients, good);
    let refused = copy(r#"{"k0":null,"ki":-1.2}"#).unwrap_err().to_string();
    assert!(refused.contains("finite"), "{refused}");
    assert!(copy(r#"{"k0":"1","ki":-1.2}"#).is_err());
    let refused = copy_with(r#"{"k0":0.5,"ki":-1.2}"#, r#"{"k0":null,"ki":1e-6}"#)
        .unwrap_err()
        .to_string();
    assert!(
        refused.contains("expanded uncertainties must be finite"),
        "{refused}"
    );
    copy(r#"{"k0":0.5,"ki":-1.2}"#).unwrap();
    let changed = db
        .execute(
            "UPDATE calibrations SET coefficients = '{}' WHERE id = ?1",
            [c.id.to_string()],
        )
        .unwrap_err()
        .to_string();
    assert!(changed.contains("never changes"), "{changed}");
}

#[tokio::test]
async fn sqlite_behind_the_cache_conforms() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cached.db");
    let store = accelcal::store::open(path.to_str().unwrap()).await.unwrap();
    conformance(store).await;
}

/// A replica behind its sensor cache and listener, as `store::open` builds
/// it, with the cache at hand; waits until the listener is connected.
async fn cached_replica(url: &str) -> (Arc<dyn Store>, Arc<SensorCache>) {
    let store = PostgresStore::cached(url).await.unwrap();
    let cache = store.cache().clone();
    until(|| cache.is_live(), "the listener to connect").await;
    (Arc::new(store), cache)
}

/// Ends every cache listener's connection to `db`; answers how many.
async fn cut_listeners(db: &pg::TestDb) -> u64 {
    db.client()
        .await
        .execute(
            "SELECT pg_terminate_backend(pid) FROM pg_stat_activity \
             WHERE datname = $1 AND application_name = $2",
            &[
                &db.name,
                &accelcal::store::postgres::listen::APPLICATION_NAME,
            ],
        )
        .await
        .unwrap()
}

/// Polls `done` every 2 ms for up to 10 s.
async fn until(mut done: impl FnMut() -> bool, what: &str) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while !done() {
        assert!(
            std::time::Instant::now() < deadline,
            "waited 10 s for {what}"
        );
        tokio::time::sleep(std::time::Duration::from_millis(2)).await;
    }
}

/// A station's writes through the cache, each followed by the reads it
/// serves: after every write the sensor stays cached (the write brought its
/// entry up to date instead of dropping it) and what the cache serves is,
/// field for field, what the engine reads from the database without it
/// (`reference`). The writes cover each rule of the sensor's summary: a
/// newer, an older and two equal `performed_at` (the later id wins the
/// tie, the earlier does not), a type assigned, a type in force but not
/// assigned, a failed verdict. `settle` is how long a notification of the
/// write has to arrive and (wrongly) drop the entry.
async fn writes_keep_their_sensor_cached(
    store: &dyn Store,
    reference: &dyn Store,
    cache: &SensorCache,
    settle: std::time::Duration,
) {
    store
        .put_sensor_type(sensor_type("NAV", 365))
        .await
        .unwrap();
    let sensor = "KEEP";
    let read = |s: &'static str| async move {
        let at = t("2026-11-22T00:00:00Z");
        let cached = store.sensor(s.into(), at).await.unwrap().unwrap();
        let truth = reference.sensor(s.into(), at).await.unwrap().unwrap();
        (cached, truth)
    };
    store
        .insert_calibration(calibration(sensor, "2026-03-01T00:00:00Z"), None)
        .await
        .unwrap();
    let (cached, truth) = read(sensor).await;
    assert_eq!(cached, truth);
    assert!(cache.contains(sensor), "the read filled the cache");

    let typed = |at: &str, verdict: Verdict, assigns: bool| NewCalibration {
        sensor_type: Some("NAV".into()),
        assigns_type: assigns,
        verdict: Some(verdict),
        due_at: Some(t(at)),
        ..calibration(sensor, at)
    };
    let tie_low = NewCalibration {
        id: Uuid::from_u128(1),
        ..calibration(sensor, "2026-04-01T00:00:00Z")
    };
    let writes = [
        (
            "newer, typed, assigning its type",
            typed("2026-04-01T00:00:00Z", Verdict::Pass, true),
        ),
        ("older", calibration(sensor, "2026-01-01T00:00:00Z")),
        (
            "a tie, the later id",
            calibration(sensor, "2026-04-01T00:00:00Z"),
        ),
        ("a tie, an earlier id", tie_low),
        (
            "newer, type in force but not assigned, failed",
            typed("2026-05-01T00:00:00Z", Verdict::Fail, false),
        ),
        (
            "newer, untyped",
            calibration(sensor, "2026-06-01T00:00:00Z"),
        ),
    ];
    let mut count = 1;
    for (what, w) in writes {
        store.insert_calibration(w, None).await.unwrap();
        count += 1;
        tokio::time::sleep(settle).await;
        assert!(
            cache.contains(sensor),
            "{what}: the write dropped its sensor"
        );
        let (cached, truth) = read(sensor).await;
        assert_eq!(
            cached, truth,
            "{what}: the cache serves what the database does not"
        );
        assert_eq!(cached.calibration_count, count, "{what}");
        let before = t("2027-01-01T00:00:00Z");
        assert_eq!(
            store
                .previous_calibration(sensor.into(), before)
                .await
                .unwrap(),
            reference
                .previous_calibration(sensor.into(), before)
                .await
                .unwrap(),
            "{what}"
        );
    }
    let (last, _) = read(sensor).await;
    assert_eq!(
        last.sensor_type.as_deref(),
        Some("NAV"),
        "assigned once, kept"
    );
    assert_eq!(last.latest.performed_at, t("2026-06-01T00:00:00Z"));
    assert_eq!(last.latest_verdict, None);
}

#[tokio::test]
async fn sqlite_writes_keep_their_sensor_cached() {
    let dir = tempfile::tempdir().unwrap();
    let inner = Arc::new(SqliteStore::open(dir.path().join("kept.db")).unwrap());
    let cache = Arc::new(SensorCache::new(CAPACITY, true));
    let tokens = Arc::new(TokenCache::new(CAPACITY, true));
    let store = CachedStore::new(inner.clone(), cache.clone(), tokens, None);
    writes_keep_their_sensor_cached(&store, &*inner, &cache, std::time::Duration::ZERO).await;
}

/// The same behind PostgreSQL's listener: the replica's own notifications
/// are echoes and drop nothing; another replica's write still drops the
/// entry.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_writes_keep_their_sensor_cached() {
    let db = pg::TestDb::create().await;
    let (store, cache) = cached_replica(&db.url).await;
    let reference = PostgresStore::open(&db.url).await.unwrap();
    let settle = std::time::Duration::from_millis(100);
    writes_keep_their_sensor_cached(&*store, &reference, &cache, settle).await;
    let (other, _) = cached_replica(&db.url).await;
    other
        .insert_calibration(calibration("KEEP", "2026-07-01T00:00:00Z"), None)
        .await
        .unwrap();
    until(
        || !cache.contains("KEEP"),
        "another replica's write to drop the entry",
    )
    .await;
    store.close().await;
    other.close().await;
}

/// Two replicas, each with its token cache: a token one revokes stops
/// authenticating at the other once the notification arrives (the window
/// is printed), at once at the one that revoked it; while the other's
/// listener is gone it reads the database.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replica_token_caches_follow_revocations() {
    let db = pg::TestDb::create().await;
    let replica = || async {
        let s = PostgresStore::cached(&db.url).await.unwrap();
        let tokens = s.tokens().clone();
        until(
            || tokens.is_live() && s.cache().is_live(),
            "the listener to connect",
        )
        .await;
        (s, tokens)
    };
    let (a, _) = replica().await;
    let (b, b_tokens) = replica().await;
    let token = |n: u128| TokenRecord {
        id: Uuid::from_u128(n),
        secret_hash: vec![7; 32],
        role: Role::Reader,
        station_id: None,
        label: None,
        created_at: t("2026-11-22T00:00:00Z"),
        revoked_at: None,
    };
    for n in [1, 2] {
        a.insert_token(token(n)).await.unwrap();
        assert_eq!(b.token(Uuid::from_u128(n)).await.unwrap(), Some(token(n)));
        assert!(
            b_tokens.contains(Uuid::from_u128(n)),
            "b's read filled its cache"
        );
    }
    assert_eq!(b.token(Uuid::from_u128(3)).await.unwrap(), None);
    assert!(
        !b_tokens.contains(Uuid::from_u128(3)),
        "an unknown id is not cached"
    );

    let at = t("2026-11-22T01:00:00Z");
    assert!(a.revoke_token(Uuid::from_u128(1), at).await.unwrap());
    assert_eq!(
        a.token(Uuid::from_u128(1))
            .await
            .unwrap()
            .unwrap()
            .revoked_at,
        Some(at),
        "the replica that revoked it serves the revocation at once"
    );
    let started = std::time::Instant::now();
    loop {
        let seen = b.token(Uuid::from_u128(1)).await.unwrap().unwrap();
        if seen.revoked_at == Some(at) {
            eprintln!(
                "replica b served a's revocation {:?} after it returned",
                started.elapsed()
            );
            break;
        }
        assert!(
            started.elapsed() < std::time::Duration::from_secs(10),
            "replica b still serves the token as valid after 10 s"
        );
        tokio::time::sleep(std::time::Duration::from_millis(1)).await;
    }
    assert!(
        b_tokens.contains(Uuid::from_u128(2)),
        "the other token stays cached"
    );

    // b's listener is cut off: b reads the database until it is back.
    cut_listeners(&db).await;
    until(|| !b_tokens.is_live(), "b to notice").await;
    assert!(
        b_tokens.is_empty(),
        "a cache without its listener is emptied"
    );
    assert!(a.revoke_token(Uuid::from_u128(2), at).await.unwrap());
    assert_eq!(
        b.token(Uuid::from_u128(2))
            .await
            .unwrap()
            .unwrap()
            .revoked_at,
        Some(at),
        "a replica without its listener read a stale token"
    );
    a.close().await;
    b.close().await;
}

#[tokio::test]
async fn postgres_behind_the_cache_conforms() {
    let db = pg::TestDb::create().await;
    let (store, _) = cached_replica(&db.url).await;
    conformance(store).await;
}

/// Two replicas, each with its cache: what one stores, the other serves
/// once the notification arrives — never the replaced calibration for
/// longer — and while its listener is gone it reads the database instead.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replica_caches_follow_each_others_writes() {
    let db = pg::TestDb::create().await;
    let (a, _) = cached_replica(&db.url).await;
    let (b, b_cache) = cached_replica(&db.url).await;
    let now = t("2026-11-22T00:00:00Z");
    let first = calibration("SHARED", "2026-01-01T00:00:00Z");
    a.insert_calibration(first.clone(), None).await.unwrap();
    // b's first reads may race the notification of a's insert, which
    // forbids them to fill; one after it does.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while b_cache.is_empty() {
        let seen = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
        assert_eq!(seen.latest.id, first.id);
        assert!(
            std::time::Instant::now() < deadline,
            "b's reads never filled its cache"
        );
    }
    for (i, day) in ["02", "03", "04"].into_iter().enumerate() {
        let newer = calibration("SHARED", &format!("2026-01-{day}T00:00:00Z"));
        a.insert_calibration(newer.clone(), None).await.unwrap();
        let started = std::time::Instant::now();
        loop {
            let s = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
            if s.latest.id == newer.id {
                assert_eq!(s.calibration_count, i as u64 + 2);
                eprintln!(
                    "replica b served a's write {:?} after a's insert returned",
                    started.elapsed()
                );
                break;
            }
            assert!(
                started.elapsed() < std::time::Duration::from_secs(10),
                "replica b still serves {} after 10 s",
                s.latest.id
            );
            tokio::time::sleep(std::time::Duration::from_millis(1)).await;
        }
        // And a's own write is seen by a at once, from its cache or not.
        let own = a.sensor("SHARED".into(), now).await.unwrap().unwrap();
        assert_eq!(own.latest.id, newer.id);
    }
    // b's listener is cut off: b bypasses its cache until it is back.
    assert_eq!(
        cut_listeners(&db).await,
        2,
        "both replicas' listeners were connected"
    );
    until(|| !b_cache.is_live(), "b to notice").await;
    let during = calibration("SHARED", "2026-02-01T00:00:00Z");
    a.insert_calibration(during.clone(), None).await.unwrap();
    let s = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
    assert_eq!(
        s.latest.id, during.id,
        "a replica without its listener read a stale entry"
    );
    until(|| b_cache.is_live(), "b's listener to reconnect").await;
    let s = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
    assert_eq!(s.latest.id, during.id);
    a.close().await;
    b.close().await;
}
