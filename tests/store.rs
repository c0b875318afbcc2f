//! Engine-agnostic conformance tests of the `Store` trait. Every engine runs
//! the same suite; a new engine adds one `#[tokio::test]` that builds it and
//! calls `conformance`.

use std::sync::Arc;

use accelcal::auth::Role;
use accelcal::store::{
    Claim, HistoryQuery, IdempotencyKey, NewCalibration, Store, Stored, TokenRecord,
    sqlite::SqliteStore,
};
use accelcal::timestamp::Timestamp;
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
        model: r#"["k0","ki"]"#.into(),
        runs: 4,
        coefficients: r#"{"k0":0.001,"ki":-1.2}"#.into(),
        std_errors: r#"{"k0":1e-6,"ki":2e-6}"#.into(),
        result: format!(r#"{{"id":"{id}"}}"#),
        submission: b"{\"raw\": true}".to_vec(),
        content_type: "application/json".into(),
        submitted_by: "tester".into(),
    }
}

fn key(k: &str, body: u8) -> IdempotencyKey {
    IdempotencyKey {
        principal: "p-1".into(),
        key: k.into(),
        request_hash: [body; 32],
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
        (sub.content_type.as_str(), sub.body.as_slice()),
        ("application/json", a.submission.as_slice())
    );
    assert!(
        s.calibration_result(Uuid::now_v7())
            .await
            .unwrap()
            .is_none()
    );

    let s1 = s.sensor("S-1".into()).await.unwrap().unwrap();
    assert_eq!(s1.calibration_count, 3);
    assert_eq!(
        s1.latest.id, b.id,
        "latest is by performed_at, not by arrival"
    );
    assert_eq!(s1.first_performed_at, "2026-01-01T00:00:00.000000Z");
    assert_eq!(s1.latest.coefficients.get(), b.coefficients);
    assert!(s.sensor("S-9".into()).await.unwrap().is_none());

    let page = s.sensors(None, 1).await.unwrap();
    assert_eq!(
        page.iter()
            .map(|x| x.sensor_id.as_str())
            .collect::<Vec<_>>(),
        ["S-1"]
    );
    let page = s.sensors(Some("S-1".into()), 10).await.unwrap();
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
        created_at: "2026-11-22T00:00:00.000000Z".into(),
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
        s.token(record.id)
            .await
            .unwrap()
            .unwrap()
            .revoked_at
            .as_deref(),
        Some("2026-11-22T01:00:00.000000Z")
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
        s.sensor("S-K".into())
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
    s.release_key("p-1".into(), "r".into()).await.unwrap();
    assert_eq!(
        s.claim_key(key("r", 4), now, lease).await.unwrap(),
        Claim::Fresh
    );
    s.release_key("p-1".into(), "k".into()).await.unwrap();
    assert_eq!(
        s.claim_key(key("k", 1), later, later).await.unwrap(),
        Claim::Done(c.id)
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

/// The whole suite, on a fresh, empty store.
async fn conformance(s: Arc<dyn Store>) {
    s.ping().await.unwrap();
    calibrations_and_sensors(s.as_ref()).await;
    tokens(s.as_ref()).await;
    idempotency(s.as_ref()).await;
    s.close().await;
}

#[tokio::test]
async fn sqlite_conforms() {
    let dir = tempfile::tempdir().unwrap();
    let store = SqliteStore::open(dir.path().join("conformance.db")).unwrap();
    conformance(Arc::new(store)).await;
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
