//! The conformance suite every engine runs, bare and behind the cache.

use super::*;
use accelcal::domain::review::Basis;
use accelcal::store::Precondition;

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
    // Every combination of the conditions, and pages shorter than what is
    // there (PostgreSQL's statement fetches a power of two: 3 fetches 4).
    assert_eq!(
        all(q(None, Some("2026-02-01T00:00:00Z"), None)).await,
        [b.id, c.id]
    );
    assert_eq!(
        all(q(None, None, Some("2026-02-01T00:00:00Z"))).await,
        [c.id, a.id]
    );
    assert_eq!(
        all(q(Some(b.id), Some("2026-01-15T00:00:00Z"), None)).await,
        [c.id]
    );
    assert_eq!(
        all(q(Some(c.id), None, Some("2026-02-15T00:00:00Z"))).await,
        [a.id]
    );
    assert_eq!(
        all(q(
            Some(b.id),
            Some("2026-01-01T00:00:00Z"),
            Some("2026-02-01T00:00:00Z")
        ))
        .await,
        [c.id, a.id]
    );
    for (limit, want) in [
        (1, &[b.id][..]),
        (2, &[b.id, c.id]),
        (3, &[b.id, c.id, a.id]),
    ] {
        let page = HistoryQuery {
            limit,
            ..q(None, None, None)
        };
        assert_eq!(all(page).await, want, "limit {limit}");
    }
    let page = HistoryQuery {
        limit: 1,
        ..q(Some(b.id), None, None)
    };
    assert_eq!(all(page).await, [c.id]);
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
        holder: Some("Ana Ruiz-Pérez".into()),
        created_at: t("2026-11-22T00:00:00Z"),
        revoked_at: None,
    };
    s.insert_token(record.clone(), admin()).await.unwrap();
    assert_eq!(s.token(record.id).await.unwrap().unwrap(), record);
    assert!(s.has_admin_token().await.unwrap());
    assert_eq!(s.tokens().await.unwrap(), vec![record.clone()]);
    assert!(
        s.revoke_token(record.id, t("2026-11-22T01:00:00Z"), admin())
            .await
            .unwrap()
    );
    assert!(
        !s.revoke_token(record.id, t("2026-11-22T02:00:00Z"), admin())
            .await
            .unwrap(),
        "revoked once only"
    );
    assert_eq!(
        s.token(record.id).await.unwrap().unwrap().revoked_at,
        Some(t("2026-11-22T01:00:00Z"))
    );
    assert!(!s.has_admin_token().await.unwrap());
    // Every role is stored, a reviewer's too; no holder is kept as none.
    let reviewer = TokenRecord {
        id: Uuid::now_v7(),
        role: Role::Reviewer,
        holder: None,
        label: None,
        ..record
    };
    s.insert_token(reviewer.clone(), admin()).await.unwrap();
    assert_eq!(s.token(reviewer.id).await.unwrap().unwrap(), reviewer);
    assert!(
        !s.has_admin_token().await.unwrap(),
        "a reviewer is not an admin"
    );
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

/// A triad's elements are stored and read back whole, by every read of a
/// calibration (summary, history, previous, the export's records); a
/// non-finite element is refused before anything is written.
async fn triads_round_trip(s: &dyn Store) {
    let elements = accelcal::store::TriadElements {
        method: "gravity_magnitude".into(),
        b: [0.183, -0.127, 0.342],
        b_std_errors: Some([1e-3, 2e-3, 3e-3]),
        s: [[1.01, 0.0, 0.0], [0.002, 0.99, 0.0], [-0.003, 0.004, 1.02]],
        s_std_errors: None,
        t: [
            [0.990_099, 0.0, 0.0],
            [-0.002, 1.010_101, 0.0],
            [0.003, -0.004, 0.980_392],
        ],
        t_std_errors: Some([[1e-4, 0.0, 0.0], [2e-4, 1e-4, 0.0], [3e-4, 2e-4, 1e-4]]),
        b_expanded: Some([2e-3, 4e-3, 6e-3]),
        s_expanded: None,
        s2: Some([1e-3, -2e-3, 3e-4]),
        s2_std_errors: Some([1e-5, 2e-5, 3e-5]),
        s2_expanded: None,
    };
    let mut c = calibration("TRIAD-1", "2026-02-01T00:00:00Z");
    c.coefficients = TermMap(vec![]);
    c.std_errors = TermMap(vec![]);
    c.expanded = None;
    c.triad = Some(Box::new(elements.clone()));
    assert_eq!(
        s.insert_calibration(c.clone(), None).await.unwrap(),
        Stored::New
    );
    let summary = s.calibration_summary(c.id).await.unwrap().unwrap();
    assert_eq!(summary.triad.as_deref(), Some(&elements));
    assert!(summary.coefficients.is_empty());
    let latest = s.sensor("TRIAD-1".into(), now()).await.unwrap().unwrap();
    assert_eq!(latest.latest.triad, Some(Box::new(elements.clone())));
    let history = s
        .history(
            "TRIAD-1".into(),
            HistoryQuery {
                limit: 10,
                ..Default::default()
            },
        )
        .await
        .unwrap();
    assert_eq!(history.len(), 1);
    assert_eq!(history[0].triad, Some(Box::new(elements.clone())));
    let mut exported = Vec::new();
    let mut after = None;
    loop {
        let page = s.export_calibrations(after, 50).await.unwrap();
        let Some(last) = page.last() else { break };
        after = Some(last.id);
        exported.extend(page);
    }
    let copied = exported.iter().find(|n| n.id == c.id).unwrap();
    assert_eq!(copied.triad, Some(Box::new(elements.clone())));
    let mut bad = calibration("TRIAD-1", "2026-03-01T00:00:00Z");
    bad.coefficients = TermMap(vec![]);
    bad.std_errors = TermMap(vec![]);
    let mut e = elements;
    e.t[1][0] = f64::NAN;
    bad.triad = Some(Box::new(e));
    let err = s.insert_calibration(bad.clone(), None).await.unwrap_err();
    assert!(matches!(err, StoreError::Refused(_)), "{err:?}");
    assert!(s.calibration_summary(bad.id).await.unwrap().is_none());
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

pub(crate) fn sensor_type(id: &str, interval_days: u32) -> SensorType {
    SensorType {
        type_id: id.into(),
        label: Some("nav".into()),
        unit: Some("mA".into()),
        limits: TermMap(vec![(
            Term::K0,
            Limit {
                min: Some(-1e-3),
                max: Some(1e-3),
            },
        )]),
        decision_rule: Rule::Guarded,
        coverage_probability: None,
        coverage_factor: Some(2.0),
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
        s.put_sensor_type(sensor_type("NAV", 365), admin(), Precondition::Any)
            .await
            .unwrap()
            .created(),
        "created"
    );
    assert!(
        !s.put_sensor_type(sensor_type("NAV", 180), admin(), Precondition::Any)
            .await
            .unwrap()
            .created(),
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
    s.put_sensor_type(sensor_type("AAA", 30), admin(), Precondition::Any)
        .await
        .unwrap();
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
        s.assign_sensor_type("ST-UNKNOWN".into(), "AAA".into(), admin())
            .await
            .unwrap()
    );
    assert!(
        !s.assign_sensor_type("NO-SUCH".into(), "AAA".into(), admin())
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
        ids(s
            .series("SER".into(), None, None, 10, Basis::NotRejected)
            .await
            .unwrap()),
        (vec![a.id, b.id, c.id], 3)
    );
    assert_eq!(
        ids(s
            .series(
                "SER".into(),
                Some(t("2026-01-15T00:00:00Z")),
                Some(t("2026-03-01T00:00:00Z")),
                10,
                Basis::NotRejected
            )
            .await
            .unwrap()),
        (vec![b.id, c.id], 2)
    );
    // The limit keeps the latest, oldest first, and counts the window.
    assert_eq!(
        ids(s
            .series("SER".into(), None, None, 2, Basis::NotRejected)
            .await
            .unwrap()),
        (vec![b.id, c.id], 3)
    );
    // A page exactly full counts the window again (the same three).
    assert_eq!(
        ids(s
            .series("SER".into(), None, None, 3, Basis::NotRejected)
            .await
            .unwrap()),
        (vec![a.id, b.id, c.id], 3)
    );
    assert_eq!(
        ids(s
            .series("NONE".into(), None, None, 10, Basis::NotRejected)
            .await
            .unwrap()),
        (vec![], 0)
    );
    let prev = |at: &'static str| async move {
        s.previous_calibration("SER".into(), t(at), Basis::NotRejected)
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
        s.previous_calibration("SER".into(), t(at), Basis::NotRejected)
            .await
            .unwrap()
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

    // The sensor's latest calibration follows a newer write, not an older
    // one (behind the cache, a hit until that write brings it up to date).
    let latest = || async {
        s.sensor("SER".into(), now())
            .await
            .unwrap()
            .map(|x| x.latest.id)
    };
    assert_eq!(latest().await, Some(c.id));
    let d = calibration("SER", "2026-04-01T00:00:00Z");
    s.insert_calibration(d.clone(), None).await.unwrap();
    assert_eq!(latest().await, Some(d.id));
    let older = calibration("SER", "2025-12-01T00:00:00Z");
    let older_id = older.id;
    s.insert_calibration(older, None).await.unwrap();
    assert_eq!(latest().await, Some(d.id));

    // History pages: newest first, a cursor continues after its calibration,
    // a window bounds both ends.
    let page = |limit: usize| HistoryQuery {
        limit,
        ..HistoryQuery::default()
    };
    let ids = |q: HistoryQuery| async {
        s.history("SER".into(), q)
            .await
            .unwrap()
            .into_iter()
            .map(|x| x.id)
            .collect::<Vec<_>>()
    };
    assert_eq!(ids(page(10)).await, [d.id, c.id, b.id, a.id, older_id]);
    assert_eq!(ids(page(2)).await, [d.id, c.id]);
    let after_c = HistoryQuery {
        before: Some(c.id),
        ..page(10)
    };
    assert_eq!(ids(after_c).await, [b.id, a.id, older_id]);

    // A full page counts the window: the whole history on the default
    // basis from the sensor's row, any other window by counting — the same
    // number both ways, and what was stored less what stopped counting.
    use accelcal::domain::auth::Principal;
    use accelcal::domain::review::{Act, Action};
    let rita = Principal {
        id: "0190aaaa000070008000000000000001".into(),
        role: Role::Reviewer,
        station_id: None,
        holder: Some("Rita".into()),
    };
    let act = |action| Act {
        action,
        signer: rita.clone(),
        at: t("2026-11-22T12:00:00Z"),
        comment: Some("series".into()),
        superseded_by: None,
    };
    done_of(s.sign(a.id, act(Action::Reject)).await.unwrap());
    done_of(s.sign(b.id, act(Action::Approve)).await.unwrap());
    let counted = |from, to, basis| async move {
        s.series("SER".into(), from, to, 1, basis)
            .await
            .unwrap()
            .in_window
    };
    let (past, future) = (
        Some(t("2000-01-01T00:00:00Z")),
        Some(t("2100-01-01T00:00:00Z")),
    );
    assert_eq!(counted(None, None, Basis::NotRejected).await, 5 - 1);
    assert_eq!(counted(past, future, Basis::NotRejected).await, 5 - 1);
    assert_eq!(counted(None, future, Basis::NotRejected).await, 5 - 1);
    assert_eq!(counted(None, None, Basis::ApprovedOnly).await, 1);
}

/// Standards round-trip exactly, are listed in id order, and make a
/// database not empty (`accelcal migrate` refuses to copy into it). Run
/// first, on the empty store.
async fn standards(s: &dyn Store) {
    use accelcal::domain::standards::StandardBody;
    let body: StandardBody =
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap();
    let stand = body.check("Z-STAND".into(), now()).unwrap();
    assert!(s.standard("Z-STAND".into()).await.unwrap().is_none());
    assert!(s.is_empty().await.unwrap());
    assert!(
        s.put_standard(stand.clone(), admin(), Precondition::Any)
            .await
            .unwrap()
            .created(),
        "created"
    );
    assert_eq!(
        s.standard("Z-STAND".into()).await.unwrap(),
        Some(stand.clone())
    );
    let mut other = stand.clone();
    other.standard_id = "A-STAND".into();
    other.angle_std_arcsec = Some(0.25);
    assert!(
        s.put_standard(other.clone(), admin(), Precondition::Any)
            .await
            .unwrap()
            .created()
    );
    let mut recalibrated = stand.clone();
    recalibrated.due_at = t("2028-01-01T00:00:00Z");
    assert!(
        !s.put_standard(recalibrated.clone(), admin(), Precondition::Any)
            .await
            .unwrap()
            .created(),
        "replaced"
    );
    assert_eq!(s.standards().await.unwrap(), [other, recalibrated]);
    assert!(!s.is_empty().await.unwrap());
}

/// Signed acts: checked against the state in the store's transaction,
/// appended in order, and the sensor's row computed again from what still
/// counts — its latest, count and earliest as a query of the survivors
/// would find them.
async fn reviews(s: &dyn Store) {
    use accelcal::domain::auth::{Principal, Role};
    use accelcal::domain::review::{Act, Action, Refusal, State};
    use accelcal::store::{HistoryQuery, Signed};
    let a = calibration("REV", "2026-01-01T00:00:00Z");
    let mut b = calibration("REV", "2026-03-01T00:00:00Z");
    b.verdict = Some(accelcal_core::decision::Verdict::Pass);
    b.due_at = Some(t("2027-03-01T00:00:00Z"));
    let c = calibration("REV", "2026-02-01T00:00:00Z");
    for x in [&a, &b, &c] {
        s.insert_calibration(x.clone(), None).await.unwrap();
    }
    let rita = Principal {
        id: "0190aaaa000070008000000000000001".into(),
        role: Role::Reviewer,
        station_id: None,
        holder: Some("Rita".into()),
    };
    let act = |action, comment: Option<&str>| Act {
        action,
        signer: rita.clone(),
        at: t("2026-11-22T12:00:00Z"),
        comment: comment.map(Into::into),
        superseded_by: None,
    };
    let done = |out: Signed| match out {
        Signed::Done(sig, sensor) => {
            assert_eq!(sensor, "REV");
            sig
        }
        other => panic!("not signed: {other:?}"),
    };
    let sensor = || async { s.sensor("REV".into(), now()).await.unwrap() };
    assert_eq!(sensor().await.unwrap().latest.id, b.id);

    // Approving the latest changes its state, not which is latest.
    let sig = done(s.sign(b.id, act(Action::Approve, None)).await.unwrap());
    assert_eq!((sig.seq, sig.state), (1, State::Approved));
    let now_b = sensor().await.unwrap();
    assert_eq!(
        (now_b.latest.id, now_b.latest.state),
        (b.id, State::Approved)
    );
    assert_eq!(now_b.calibration_count, 3);
    assert_eq!(
        s.sign(b.id, act(Action::Approve, None)).await.unwrap(),
        Signed::Refused(Refusal::State {
            state: State::Approved,
            target_past: "approved",
            from: "submitted or under-review"
        })
    );
    assert_eq!(
        s.sign(Uuid::now_v7(), act(Action::Approve, None))
            .await
            .unwrap(),
        Signed::NotFound
    );

    // Rejecting C and withdrawing B leave A: count, earliest, latest, and
    // the latest's verdict and due date all A's.
    done(s.sign(c.id, act(Action::Reject, Some("no"))).await.unwrap());
    assert_eq!(sensor().await.unwrap().calibration_count, 2);
    let sig = done(
        s.sign(b.id, act(Action::Withdraw, Some("moved")))
            .await
            .unwrap(),
    );
    assert_eq!((sig.seq, sig.comment.as_deref()), (2, Some("moved")));
    let left = sensor().await.unwrap();
    assert_eq!(left.latest.id, a.id);
    assert_eq!(left.calibration_count, 1);
    assert_eq!(
        (left.first_performed_at, left.latest_performed_at),
        (a.performed_at, a.performed_at)
    );
    assert_eq!((left.latest_verdict, left.due_at), (None, None));

    // What counts on each basis.
    let far = t("2030-01-01T00:00:00Z");
    let previous = |basis| async move {
        s.previous_calibration("REV".into(), far, basis)
            .await
            .unwrap()
            .map(|x| x.id)
    };
    assert_eq!(previous(Basis::NotRejected).await, Some(a.id));
    assert_eq!(previous(Basis::ApprovedOnly).await, None);
    assert_eq!(s.latest_approved("REV".into()).await.unwrap(), None);
    done(s.sign(a.id, act(Action::Approve, None)).await.unwrap());
    assert_eq!(previous(Basis::ApprovedOnly).await, Some(a.id));
    assert_eq!(
        s.latest_approved("REV".into()).await.unwrap().map(|x| x.id),
        Some(a.id)
    );
    let series = s
        .series("REV".into(), None, None, 10, Basis::ApprovedOnly)
        .await
        .unwrap();
    assert_eq!(
        series.items.iter().map(|x| x.id).collect::<Vec<_>>(),
        [a.id]
    );

    // Withdrawn too: no sensor any more, the history whole with states.
    done(
        s.sign(a.id, act(Action::Withdraw, Some("gone")))
            .await
            .unwrap(),
    );
    assert!(sensor().await.is_none());
    assert!(
        s.latest_calibration_id("REV".into())
            .await
            .unwrap()
            .is_none()
    );
    let q = HistoryQuery {
        from: None,
        to: None,
        before: None,
        limit: 10,
    };
    assert_eq!(
        s.history_ids("REV".into(), q.clone()).await.unwrap(),
        [
            (b.id, State::Withdrawn),
            (c.id, State::Rejected),
            (a.id, State::Withdrawn)
        ]
    );
    let states: Vec<State> = s
        .history("REV".into(), q)
        .await
        .unwrap()
        .iter()
        .map(|x| x.state)
        .collect();
    assert_eq!(
        states,
        [State::Withdrawn, State::Rejected, State::Withdrawn]
    );
    let sigs = s.signatures(a.id).await.unwrap();
    let acts: Vec<(u32, Action)> = sigs.iter().map(|x| (x.seq, x.action)).collect();
    assert_eq!(acts, [(1, Action::Approve), (2, Action::Withdraw)]);
    assert_eq!(sigs[0].holder.as_deref(), Some("Rita"));
    assert_eq!(sigs[1].signed_at, t("2026-11-22T12:00:00Z"));

    // A new calibration brings the sensor back, alone.
    let d = calibration("REV", "2026-01-15T00:00:00Z");
    s.insert_calibration(d.clone(), None).await.unwrap();
    let back = sensor().await.unwrap();
    assert_eq!((back.latest.id, back.calibration_count), (d.id, 1));

    // Supersession: the replacement and the act, both or neither.
    let supersede = |by: Uuid| {
        accelcal::domain::review::supersession(
            "corrected".into(),
            rita.clone(),
            t("2026-11-22T13:00:00Z"),
            by,
        )
    };
    let refused = calibration("REV-FIXED", "2026-01-15T00:00:00Z");
    assert!(matches!(
        s.supersede(a.id, refused.clone(), supersede(refused.id))
            .await
            .unwrap(),
        Signed::Refused(Refusal::State {
            state: State::Withdrawn,
            ..
        })
    ));
    assert!(
        s.calibration_result(refused.id).await.unwrap().is_none(),
        "nothing stored"
    );
    assert!(s.sensor("REV-FIXED".into(), now()).await.unwrap().is_none());
    let fixed = calibration("REV-FIXED", "2026-01-15T00:00:00Z");
    let sig = done_of(
        s.supersede(d.id, fixed.clone(), supersede(fixed.id))
            .await
            .unwrap(),
    );
    assert_eq!(
        (sig.state, sig.superseded_by),
        (State::Superseded, Some(fixed.id))
    );
    assert!(sensor().await.is_none(), "REV has nothing left that counts");
    let f = s.sensor("REV-FIXED".into(), now()).await.unwrap().unwrap();
    assert_eq!((f.latest.id, f.calibration_count), (fixed.id, 1));
    assert_eq!(s.signatures(d.id).await.unwrap(), [sig]);
}

fn done_of(out: accelcal::store::Signed) -> accelcal::domain::review::Signature {
    match out {
        accelcal::store::Signed::Done(sig, _) => sig,
        other => panic!("not signed: {other:?}"),
    }
}

/// Customers and items: created, replaced, read back as written.
async fn customers(s: &dyn Store) {
    use accelcal::domain::customers::{Customer, Item};
    let at = t("2026-11-25T00:00:00Z");
    let acme = Customer {
        customer_id: "ACME".into(),
        name: "Acme Navigation".into(),
        address: Some("1 Gyro Way".into()),
        contact: None,
        due_date_agreed: false,
        updated_at: at,
    };
    assert!(
        s.put_customer(acme.clone(), admin(), Precondition::Any)
            .await
            .unwrap()
            .created(),
        "created"
    );
    let agreed = Customer {
        due_date_agreed: true,
        updated_at: t("2026-11-26T00:00:00Z"),
        ..acme.clone()
    };
    assert!(
        !s.put_customer(agreed.clone(), admin(), Precondition::Any)
            .await
            .unwrap()
            .created(),
        "replaced"
    );
    assert_eq!(
        s.customer("ACME".into()).await.unwrap(),
        Some(agreed.clone())
    );
    assert_eq!(s.customer("NOPE".into()).await.unwrap(), None);
    let beta = Customer {
        customer_id: "BETA".into(),
        ..acme
    };
    s.put_customer(beta.clone(), admin(), Precondition::Any)
        .await
        .unwrap();
    assert_eq!(s.customers().await.unwrap(), [agreed, beta]);
    let item = Item {
        sensor_id: "ITEM-1".into(),
        manufacturer: Some("Honeywell".into()),
        model: Some("QA-3000".into()),
        serial: Some("Ω-1".into()),
        customer: Some("ACME".into()),
        updated_at: at,
    };
    assert!(
        s.put_item(item.clone(), admin(), Precondition::Any)
            .await
            .unwrap()
            .created()
    );
    assert_eq!(s.item("ITEM-1".into()).await.unwrap(), Some(item.clone()));
    assert_eq!(s.items().await.unwrap(), [item]);
    assert!(!s.is_empty().await.unwrap());
}

/// The whole suite, on a fresh, empty store.
async fn conformance(s: Arc<dyn Store>) {
    s.ping().await.unwrap();
    standards(s.as_ref()).await;
    customers(s.as_ref()).await;
    calibrations_and_sensors(s.as_ref()).await;
    tokens(s.as_ref()).await;
    idempotency(s.as_ref()).await;
    non_finite_values_are_refused(s.as_ref()).await;
    numbers_round_trip_exactly(s.as_ref()).await;
    triads_round_trip(s.as_ref()).await;
    types_and_statuses(s.as_ref()).await;
    series_and_previous(s.as_ref()).await;
    reviews(s.as_ref()).await;
    super::fitted::constituents(s.as_ref()).await;
    search(s.as_ref()).await;
    sessions(s.as_ref()).await;
    super::audit::trail(s.as_ref()).await;
    super::webhooks::endpoints(s.as_ref()).await;
    super::webhooks::announcements(s.as_ref()).await;
    s.close().await;
}

#[tokio::test]
async fn sqlite_conforms() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(dir.path().join("conformance.db")).unwrap();
    conformance(Arc::new(store)).await;
}

#[tokio::test]
async fn postgres_conforms() {
    let db = pg::TestDb::create().await;
    let store = PostgresStore::open(&db.url).await.unwrap();
    conformance(Arc::new(store)).await;
}

#[tokio::test]
async fn sqlite_behind_the_cache_conforms() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cached.db");
    let store = accelcal::store::open(path.to_str().unwrap()).await.unwrap();
    conformance(store).await;
}

#[tokio::test]
async fn postgres_behind_the_cache_conforms() {
    let db = pg::TestDb::create().await;
    let (store, _) = cached_replica(&db.url).await;
    conformance(store).await;
}
