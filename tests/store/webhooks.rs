//! Webhook endpoints in the store: registered and changed, leased to one
//! holder at a time, settled only by their holder, redelivered, deleted —
//! every engine alike (called from the conformance suite), and two handles
//! claiming at once on one database.

use std::sync::Arc;

use accelcal::domain::audit::Actor;
use accelcal::domain::timestamp::Timestamp;
use accelcal::domain::webhooks::{Definition, Delivery, Outcome, Secret};
use accelcal::store::prelude::*;
use accelcal::store::{Settle, postgres::PostgresStore};
use accelcal_testkit::pg;
use uuid::Uuid;

use super::t;

fn def(id: &str) -> Definition {
    Definition {
        webhook_id: id.into(),
        url: "https://control.example.com/hook".into(),
        event_types: vec![],
        sensors: vec!["S-1".into()],
        description: None,
    }
}

fn attempt(seq: i64, at: Timestamp, outcome: Outcome) -> Delivery {
    Delivery {
        event_seq: seq,
        message_id: format!("evt_{seq}"),
        attempt: 1,
        at,
        outcome,
        status: Some(503),
        error: None,
        duration_ms: 12,
    }
}

/// The whole life of an endpoint on one store.
pub async fn endpoints(s: &dyn Store) {
    let now = t("2026-11-28T10:00:00Z");
    let secret = Secret::generate().unwrap();
    let (e, created) = s
        .put_webhook(def("w"), secret.clone(), 5, now, Actor::service())
        .await
        .unwrap();
    assert!(created);
    assert_eq!((e.cursor, e.failed, e.next_attempt_at), (5, 0, now));
    assert_eq!(e.secrets.current, secret);
    // A change keeps the secret and the cursor.
    let mut changed = def("w");
    changed.url = "https://control.example.com/other".into();
    let (e, created) = s
        .put_webhook(
            changed,
            Secret::generate().unwrap(),
            99,
            now,
            Actor::service(),
        )
        .await
        .unwrap();
    assert!(!created);
    assert_eq!(
        (e.def.url.as_str(), e.cursor),
        ("https://control.example.com/other", 5)
    );
    assert_eq!(e.secrets.current, secret);
    // Nothing to deliver while the head is at the cursor.
    let (a, b) = (Uuid::now_v7(), Uuid::now_v7());
    let lease = t("2026-11-28T10:00:15Z");
    assert!(s.claim_webhook(5, now, (a, lease)).await.unwrap().is_none());
    // One holder at a time; another only once the lease expired.
    let got = s.claim_webhook(9, now, (a, lease)).await.unwrap().unwrap();
    assert_eq!(got.def.webhook_id, "w");
    assert!(s.claim_webhook(9, now, (b, lease)).await.unwrap().is_none());
    let later = t("2026-11-28T10:00:16Z");
    let retaken = s
        .claim_webhook(9, later, (b, t("2026-11-28T10:00:31Z")))
        .await
        .unwrap();
    assert!(retaken.is_some(), "an expired lease is taken over");
    // The first holder lost it: its settle changes nothing but is logged.
    let failed = Settle {
        cursor: 5,
        failed: 1,
        next_attempt_at: t("2026-11-28T10:00:21Z"),
        delivery: Some(attempt(6, now, Outcome::Failed)),
        hold_until: None,
    };
    assert!(
        !s.settle_webhook("w".into(), a, failed.clone())
            .await
            .unwrap()
    );
    assert!(s.settle_webhook("w".into(), b, failed).await.unwrap());
    let e = s.webhook("w".into()).await.unwrap().unwrap();
    assert_eq!((e.cursor, e.failed), (5, 1));
    // Not due before its next attempt.
    assert!(
        s.claim_webhook(9, later, (a, lease))
            .await
            .unwrap()
            .is_none()
    );
    let due = t("2026-11-28T10:00:21Z");
    assert!(
        s.claim_webhook(9, due, (a, t("2026-11-28T10:00:40Z")))
            .await
            .unwrap()
            .is_some()
    );
    // Delivered with more to come: the lease is renewed, still a's.
    let delivered = Settle {
        cursor: 6,
        failed: 0,
        next_attempt_at: due,
        delivery: Some(attempt(6, due, Outcome::Delivered)),
        hold_until: Some(t("2026-11-28T10:01:00Z")),
    };
    assert!(s.settle_webhook("w".into(), a, delivered).await.unwrap());
    let after_old_lease = t("2026-11-28T10:00:50Z");
    assert!(
        s.claim_webhook(9, after_old_lease, (b, lease))
            .await
            .unwrap()
            .is_none()
    );
    let done = Settle {
        cursor: 6,
        failed: 0,
        next_attempt_at: due,
        delivery: None,
        hold_until: None,
    };
    assert!(s.settle_webhook("w".into(), a, done).await.unwrap());
    let log = s.deliveries("w".into(), 10).await.unwrap();
    let outcomes: Vec<Outcome> = log.iter().map(|d| d.outcome).collect();
    assert_eq!(
        outcomes,
        [Outcome::Delivered, Outcome::Failed, Outcome::Failed]
    );
    assert_eq!(s.deliveries("w".into(), 1).await.unwrap().len(), 1);
    // Redelivery: back to the cursor asked, due at once, any lease ended.
    s.claim_webhook(9, due, (a, t("2026-11-28T10:05:00Z")))
        .await
        .unwrap()
        .unwrap();
    let e = s
        .redeliver_webhook("w".into(), 2, due, Actor::service())
        .await
        .unwrap()
        .unwrap();
    assert_eq!((e.cursor, e.failed), (2, 0));
    assert!(
        s.claim_webhook(9, due, (b, lease)).await.unwrap().is_some(),
        "the lease ended"
    );
    // Rotation keeps the old secret beside the new until the overlap ends.
    let new = Secret::generate().unwrap();
    let until = t("2026-11-29T10:00:00Z");
    let e = s
        .rotate_webhook("w".into(), new.clone(), until, due, Actor::service())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(e.secrets.current, new);
    assert_eq!(e.secrets.previous, Some((secret, until)));
    assert!(
        s.rotate_webhook("none".into(), new, until, due, Actor::service())
            .await
            .unwrap()
            .is_none()
    );
    // Listed, deleted with its log.
    s.put_webhook(
        def("a"),
        Secret::generate().unwrap(),
        0,
        now,
        Actor::service(),
    )
    .await
    .unwrap();
    let ids: Vec<String> = s
        .webhooks()
        .await
        .unwrap()
        .into_iter()
        .map(|e| e.def.webhook_id)
        .collect();
    assert_eq!(ids, ["a", "w"]);
    assert!(
        s.delete_webhook("w".into(), due, Actor::service())
            .await
            .unwrap()
    );
    assert!(
        !s.delete_webhook("w".into(), due, Actor::service())
            .await
            .unwrap()
    );
    assert!(s.webhook("w".into()).await.unwrap().is_none());
    assert!(s.deliveries("w".into(), 10).await.unwrap().is_empty());
    assert!(
        s.delete_webhook("a".into(), due, Actor::service())
            .await
            .unwrap()
    );
}

/// Statuses by the clock: announced once per change, `from` the status
/// announced for the same due date (none after a new calibration).
pub async fn announcements(s: &dyn Store) {
    use accelcal::domain::status::Status::{DueSoon, Overdue};
    let (d1, d2) = (t("2026-12-01T00:00:00Z"), t("2027-06-01T00:00:00Z"));
    let at = t("2026-11-28T10:00:00Z");
    assert_eq!(
        s.announce_statuses(vec![("ANN-1".into(), DueSoon, d1)], at)
            .await
            .unwrap(),
        1
    );
    assert_eq!(
        s.announce_statuses(vec![("ANN-1".into(), DueSoon, d1)], at)
            .await
            .unwrap(),
        0
    );
    assert_eq!(
        s.announce_statuses(vec![("ANN-1".into(), Overdue, d1)], at)
            .await
            .unwrap(),
        1
    );
    assert_eq!(
        s.announce_statuses(vec![("ANN-1".into(), DueSoon, d2)], at)
            .await
            .unwrap(),
        1
    );
    let q = accelcal::store::AuditQuery {
        object: Some("sensors/ANN-1".into()),
        limit: 100,
        ..Default::default()
    };
    let changes: Vec<String> = s
        .audit(q)
        .await
        .unwrap()
        .into_iter()
        .filter(|e| e.action == "sensor.status")
        .map(|e| e.change)
        .collect();
    assert_eq!(
        changes,
        [
            r#"{"due_at":"2026-12-01T00:00:00.000000Z","from":null,"to":"due_soon"}"#,
            r#"{"due_at":"2026-12-01T00:00:00.000000Z","from":"due_soon","to":"overdue"}"#,
            r#"{"due_at":"2027-06-01T00:00:00.000000Z","from":null,"to":"due_soon"}"#,
        ]
    );
    assert_eq!(
        s.announced_statuses().await.unwrap(),
        [("ANN-1".to_owned(), DueSoon, d2)]
    );
}

/// Two replicas announcing the same changes at once announce each once.
#[tokio::test]
async fn two_replicas_announce_a_change_once() {
    use accelcal::domain::status::Status::Overdue;
    let db = pg::TestDb::create().await;
    let one: Arc<dyn Store> = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let two: Arc<dyn Store> = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let at = t("2026-11-28T10:00:00Z");
    let changes: Vec<_> = (0..50)
        .map(|i| (format!("S-{i}"), Overdue, t("2026-11-01T00:00:00Z")))
        .collect();
    let (x, y) = tokio::join!(
        one.announce_statuses(changes.clone(), at),
        two.announce_statuses(changes.clone(), at),
    );
    assert_eq!(x.unwrap() + y.unwrap(), 50);
    let q = accelcal::store::AuditQuery {
        limit: 1000,
        ..Default::default()
    };
    let announced = one
        .audit(q)
        .await
        .unwrap()
        .into_iter()
        .filter(|e| e.action == "sensor.status")
        .count();
    assert_eq!(announced, 50);
}

/// Two replicas' handles claiming one endpoint at once: exactly one gets it.
#[tokio::test]
async fn two_replicas_never_hold_one_endpoint_at_once() {
    let db = pg::TestDb::create().await;
    let one: Arc<dyn Store> = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let two: Arc<dyn Store> = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let now = t("2026-11-28T10:00:00Z");
    one.put_webhook(
        def("w"),
        Secret::generate().unwrap(),
        0,
        now,
        Actor::service(),
    )
    .await
    .unwrap();
    for round in 0..20 {
        let lease = now.plus_seconds(60 * (round + 1));
        let at = now.plus_seconds(60 * round + 1);
        let (x, y) = tokio::join!(
            one.claim_webhook(1, at, (Uuid::now_v7(), lease)),
            two.claim_webhook(1, at, (Uuid::now_v7(), lease)),
        );
        let held = [x.unwrap(), y.unwrap()].into_iter().flatten().count();
        assert_eq!(held, 1, "round {round}");
    }
}
