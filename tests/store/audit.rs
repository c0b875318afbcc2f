//! The audit trail on both engines: what each act appends, the chain
//! recomputed independently of the code under test, filters and pages, the
//! trail tampered with behind the service's back (and found by `verify`),
//! two PostgreSQL replicas appending at once to one chain, and acts that
//! never wait for the chain's lock there (its sealer does).

use std::collections::BTreeSet;

use accelcal::domain::audit::{Entry, GENESIS};
use accelcal::domain::auth::Principal;
use accelcal::domain::review::{Act, Action};
use accelcal::store::Precondition;
use accelcal::store::audit::{VerifyError, verify};
use accelcal::store::{AuditQuery, Signed};
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

use super::*;

/// Every entry, paging through `GET /v1/audit`'s store query.
async fn everything(s: &dyn Store) -> Vec<Entry> {
    let mut out: Vec<Entry> = Vec::new();
    loop {
        let after = out.last().map_or(0, |e| e.seq);
        let page = s
            .audit(AuditQuery {
                after,
                limit: 7,
                ..AuditQuery::default()
            })
            .await
            .unwrap();
        if page.is_empty() {
            return out;
        }
        assert!(page.len() <= 7);
        out.extend(page);
    }
}

/// The hash of an entry as the module documents it, computed here with
/// `json!` (whose maps sort their keys) and SHA-256, not with the code's
/// canonical form.
fn independent_hash(e: &Entry) -> String {
    let change: Value = serde_json::from_str(&e.change).unwrap();
    let canonical = json!({
        "seq": e.seq,
        "at": e.at.to_string(),
        "actor": {"token_id": e.actor.token_id, "role": e.actor.role, "holder": e.actor.holder},
        "action": e.action,
        "object": e.object,
        "change": change,
        "prev": e.prev,
    })
    .to_string();
    hex::encode(Sha256::digest(canonical.as_bytes()))
}

fn reviewer(holder: &str) -> Principal {
    Principal {
        id: "0190aaaa000070008000000000000077".into(),
        role: Role::Reviewer,
        station_id: None,
        holder: Some(holder.into()),
    }
}

/// Run last in the conformance suite: every act before it is in the trail.
pub async fn trail(s: &dyn Store) {
    let before = everything(s).await;
    let actions: BTreeSet<&str> = before.iter().map(|e| e.action.as_str()).collect();
    for expected in [
        "calibration.submitted",
        "calibration.approve",
        "calibration.reject",
        "calibration.withdraw",
        "calibration.supersede",
        "token.create",
        "token.revoke",
        "sensor_type.put",
        "sensor.retype",
        "standard.put",
        "customer.put",
        "item.put",
    ] {
        assert!(actions.contains(expected), "no {expected} in {actions:?}");
    }
    // The chain, recomputed here.
    for (i, e) in before.iter().enumerate() {
        assert_eq!(e.seq, i as i64 + 1, "sequence without gaps");
        let prev = if i == 0 { GENESIS } else { &before[i - 1].hash };
        assert_eq!(&e.prev, prev, "entry {} names its predecessor", e.seq);
        assert_eq!(e.hash, independent_hash(e), "entry {}", e.seq);
    }

    // A station submits, a reviewer approves: two entries on the object,
    // each with its actor as the tokens table and the signature say.
    let station = TokenRecord {
        id: Uuid::now_v7(),
        secret_hash: vec![9; 32],
        role: Role::Station,
        station_id: Some("LAB-1".into()),
        label: None,
        holder: Some("Sam".into()),
        created_at: t("2026-11-22T00:00:00Z"),
        revoked_at: None,
    };
    s.insert_token(station.clone(), admin()).await.unwrap();
    let mut c = calibration("AUD", "2026-05-01T00:00:00Z");
    c.submitted_by = station.id.to_string();
    s.insert_calibration(c.clone(), Some(key("audit", 1)))
        .await
        .unwrap();
    // The same key again (a retry: a new id) stores nothing, and appends
    // nothing.
    let retry = NewCalibration {
        id: Uuid::now_v7(),
        ..c.clone()
    };
    assert_eq!(
        s.insert_calibration(retry, Some(key("audit", 1)))
            .await
            .unwrap(),
        accelcal::store::Stored::Existing(c.id)
    );
    let act = |action| Act {
        action,
        signer: reviewer("Rita Audit"),
        at: t("2026-11-23T09:00:00Z"),
        comment: Some("fine".into()),
        superseded_by: None,
    };
    assert!(matches!(
        s.sign(c.id, act(Action::Approve)).await.unwrap(),
        Signed::Done(..)
    ));
    // A refused act appends nothing.
    assert!(matches!(
        s.sign(c.id, act(Action::Approve)).await.unwrap(),
        Signed::Refused(_)
    ));
    let object = format!("calibrations/{}", c.id);
    let own = s
        .audit(AuditQuery {
            object: Some(object.clone()),
            limit: 100,
            ..AuditQuery::default()
        })
        .await
        .unwrap();
    let summary: Vec<(&str, &str, &str, Option<&str>)> = own
        .iter()
        .map(|e| {
            (
                e.action.as_str(),
                e.actor.token_id.as_str(),
                e.actor.role.as_str(),
                e.actor.holder.as_deref(),
            )
        })
        .collect();
    let station_id = station.id.to_string();
    assert_eq!(
        summary,
        [
            (
                "calibration.submitted",
                station_id.as_str(),
                "station",
                Some("Sam")
            ),
            (
                "calibration.approve",
                "0190aaaa000070008000000000000077",
                "reviewer",
                Some("Rita Audit")
            ),
        ]
    );
    let submitted: Value = serde_json::from_str(&own[0].change).unwrap();
    assert_eq!(
        submitted["submission_sha256"],
        hex::encode(Sha256::digest(&c.submission)),
    );
    assert_eq!(
        submitted["result_sha256"],
        hex::encode(Sha256::digest(&c.result))
    );
    assert_eq!(submitted["sensor_id"], "AUD");
    assert_eq!(own[0].at, c.received_at);
    let approved: Value = serde_json::from_str(&own[1].change).unwrap();
    assert_eq!(
        (&approved["from"], &approved["to"], &approved["comment"]),
        (&json!("submitted"), &json!("approved"), &json!("fine"))
    );
    assert_eq!(own[1].at, t("2026-11-23T09:00:00Z"));
    let after = everything(s).await;
    assert_eq!(
        after.len(),
        before.len() + 3,
        "token, submission, approval; nothing for the replay or the refusal"
    );

    // Filters: by holder or token id, and by time.
    let by_rita = s
        .audit(AuditQuery {
            actor: Some("Rita Audit".into()),
            limit: 100,
            ..AuditQuery::default()
        })
        .await
        .unwrap();
    assert_eq!(by_rita, own[1..].to_vec());
    let by_token = s
        .audit(AuditQuery {
            actor: Some(station_id.clone()),
            limit: 100,
            ..AuditQuery::default()
        })
        .await
        .unwrap();
    assert_eq!(by_token, own[..1].to_vec());
    let on_the_23rd = s
        .audit(AuditQuery {
            from: Some(t("2026-11-23T00:00:00Z")),
            to: Some(t("2026-11-23T23:59:59Z")),
            limit: 100,
            ..AuditQuery::default()
        })
        .await
        .unwrap();
    assert!(on_the_23rd.contains(&own[1]));
    assert!(
        on_the_23rd
            .iter()
            .all(|e| e.at >= t("2026-11-23T00:00:00Z") && e.at <= t("2026-11-23T23:59:59Z"))
    );

    // The configuration: recorded when it changes, not at every start.
    let settings = |on: bool| serde_json::Map::from_iter([("require_approval".into(), on.into())]);
    assert!(s.configure(settings(false)).await.unwrap());
    assert!(!s.configure(settings(false)).await.unwrap());
    assert!(s.configure(settings(true)).await.unwrap());
    let last = everything(s).await.pop().unwrap();
    assert_eq!(
        (
            last.action.as_str(),
            last.object.as_str(),
            last.actor.role.as_str()
        ),
        ("service.configure", "service", "service")
    );
    assert_eq!(last.change, r#"{"require_approval":true}"#);

    // And the whole of it verifies, every calibration's bytes included.
    let v = verify(s).await.unwrap();
    let all = everything(s).await;
    assert_eq!(v.head_seq, all.len() as i64);
    assert_eq!(v.head_hash, all.last().unwrap().hash);
    assert_eq!(
        v.calibrations,
        all.iter()
            .filter(|e| e.action == "calibration.submitted")
            .count() as i64
    );
}

/// What `verify` says of a store, as text.
async fn broken(s: &dyn Store) -> String {
    match verify(s).await {
        Err(VerifyError::Broken(b)) => b.to_string(),
        other => panic!("verified: {other:?}"),
    }
}

/// A few acts on a fresh store.
async fn some_acts(s: &dyn Store) -> Vec<NewCalibration> {
    let mut out = Vec::new();
    for (n, at) in [
        "2026-01-01T00:00:00Z",
        "2026-02-01T00:00:00Z",
        "2026-03-01T00:00:00Z",
    ]
    .into_iter()
    .enumerate()
    {
        let c = calibration(&format!("TAMPER-{n}"), at);
        s.insert_calibration(c.clone(), None).await.unwrap();
        out.push(c);
    }
    s.put_sensor_type(super::sensor_type("NAV", 365), admin(), Precondition::Any)
        .await
        .unwrap();
    out
}

/// An entry edited, a row inserted and a row deleted, each made with SQL
/// directly (`sql`), each found and named by `verify` on a store opened
/// afresh (`store`); between them the trail is put back and verifies.
async fn tampering<S, Q, F>(store: S, sql: Q, head_hash_of_4: String)
where
    S: Fn() -> F,
    F: std::future::Future<Output = Box<dyn Store>>,
    Q: AsyncFn(&str),
{
    // Edited: named by its own hash.
    sql("UPDATE audit SET holder = 'Mallory' WHERE seq = 1").await;
    let why = broken(store().await.as_ref()).await;
    assert!(
        why.starts_with("audit entry 1:") && why.contains("edited"),
        "{why}"
    );
    sql("UPDATE audit SET holder = NULL WHERE seq = 1").await;
    assert_eq!(verify(store().await.as_ref()).await.unwrap().head_seq, 4);
    // Inserted after the head, its hash made up: named.
    sql(&format!(
        "INSERT INTO audit (seq, at, token_id, role, holder, action, object, change, prev, hash) \
         VALUES (5, '2026-11-24T00:00:00Z', 'x', 'admin', NULL, 'token.create', 'tokens/x', \
         '{{}}', '{head_hash_of_4}', 'beef')"
    ))
    .await;
    let why = broken(store().await.as_ref()).await;
    assert!(
        why.starts_with("audit entry 5:") && why.contains("not the hash of its content"),
        "{why}"
    );
    // Inserted with a number of its own: the numbering breaks.
    sql("UPDATE audit SET seq = 6 WHERE seq = 5").await;
    let why = broken(store().await.as_ref()).await;
    assert!(
        why.starts_with("audit entry 5:") && why.contains("numbered 6"),
        "{why}"
    );
    sql("DELETE FROM audit WHERE seq = 6").await;
    assert_eq!(verify(store().await.as_ref()).await.unwrap().head_seq, 4);
    // Deleted: named by the number missing.
    sql("DELETE FROM audit WHERE seq = 3").await;
    let why = broken(store().await.as_ref()).await;
    assert!(
        why.starts_with("audit entry 3:") && why.contains("missing"),
        "{why}"
    );
}

#[tokio::test]
async fn sqlite_tampering_is_found() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tamper.db");
    let s = SqliteStore::open(&path).unwrap();
    let stored = some_acts(&s).await;
    let head = verify(&s).await.unwrap();
    assert_eq!(head.head_seq, 4);
    s.close().await;
    drop(s);
    let sql = async |statements: &str| {
        rusqlite::Connection::open(&path)
            .unwrap()
            .execute_batch(statements)
            .unwrap();
    };
    let open = || async { Box::new(SqliteStore::open(&path).unwrap()) as Box<dyn Store> };
    // The triggers refuse an edit made through SQL as it stands.
    let refused = rusqlite::Connection::open(&path)
        .unwrap()
        .execute("UPDATE audit SET role = 'admin' WHERE seq = 2", [])
        .unwrap_err();
    assert!(refused.to_string().contains("never changes"), "{refused}");

    // A calibration's stored result edited, its trigger dropped first.
    sql(&format!(
        "DROP TRIGGER calibrations_immutable; \
         UPDATE calibrations SET result = '{{\"forged\":true}}' WHERE id = '{}'",
        stored[1].id
    ))
    .await;
    let why = broken(open().await.as_ref()).await;
    assert!(
        why.starts_with("audit entry 2:") && why.contains("stored result is not the one recorded"),
        "{why}"
    );
    sql(&format!(
        "UPDATE calibrations SET result = '{}' WHERE id = '{}'; \
         DROP TRIGGER audit_immutable; DROP TRIGGER audit_kept",
        std::str::from_utf8(&stored[1].result).unwrap(),
        stored[1].id
    ))
    .await;
    tampering(open, sql, head.head_hash).await;
}

#[tokio::test]
async fn postgres_tampering_is_found() {
    let db = pg::TestDb::create().await;
    let s = PostgresStore::open(&db.url).await.unwrap();
    some_acts(&s).await;
    let head = verify(&s).await.unwrap();
    assert_eq!(head.head_seq, 4);
    let client = db.client().await;
    let refused = client
        .batch_execute("UPDATE audit SET role = 'admin' WHERE seq = 2")
        .await
        .unwrap_err();
    assert!(
        format!("{refused:?}").contains("never changes"),
        "{refused:?}"
    );
    client
        .batch_execute("ALTER TABLE audit DISABLE TRIGGER audit_kept")
        .await
        .unwrap();
    let sql = async |statements: &str| client.batch_execute(statements).await.unwrap();
    let url = db.url.clone();
    let open = || {
        let url = url.clone();
        async move { Box::new(PostgresStore::open(&url).await.unwrap()) as Box<dyn Store> }
    };
    tampering(open, sql, head.head_hash).await;
    s.close().await;
}

/// Rita's approval, now.
fn approval() -> Act {
    Act {
        action: Action::Approve,
        signer: reviewer("Rita"),
        at: Timestamp::now(),
        comment: None,
        superseded_by: None,
    }
}

/// Two replicas submitting and signing at once append to one chain, in
/// order, without a gap or a fork.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replicas_append_to_one_chain() {
    let db = pg::TestDb::create().await;
    let a = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let b = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let mut tasks = Vec::new();
    for i in 0..40 {
        let s: Arc<PostgresStore> = if i % 2 == 0 { a.clone() } else { b.clone() };
        tasks.push(tokio::spawn(async move {
            let c = calibration(&format!("REP-{}", i % 5), "2026-04-01T00:00:00Z");
            s.insert_calibration(c.clone(), None).await.unwrap();
            let approve = approval();
            assert!(matches!(
                s.sign(c.id, approve).await.unwrap(),
                Signed::Done(..)
            ));
        }));
    }
    for t in tasks {
        t.await.unwrap();
    }
    let v = verify(a.as_ref()).await.unwrap();
    assert_eq!(v.head_seq, 80, "40 submissions and 40 approvals");
    assert_eq!(v.unsealed, 0);
    assert_eq!(v.calibrations, 40);
    let from_b = everything(b.as_ref()).await;
    assert_eq!(from_b.last().unwrap().hash, v.head_hash);
    // Each approval follows its own calibration's submission.
    for e in from_b.iter().filter(|e| e.action == "calibration.approve") {
        let submitted = from_b
            .iter()
            .find(|s| s.object == e.object && s.action == "calibration.submitted")
            .unwrap();
        assert!(submitted.seq < e.seq);
    }
}

/// The number of entries sealed into PostgreSQL's chain and still pending,
/// read directly.
async fn chained_and_pending(client: &tokio_postgres::Client) -> (i64, i64) {
    let r = client
        .query_one(
            "SELECT (SELECT count(*) FROM audit), (SELECT count(*) FROM audit_pending)",
            &[],
        )
        .await
        .unwrap();
    (r.get(0), r.get(1))
}

/// Waits (up to a minute, so that a slow machine cannot fail it) until
/// `n` entries are chained and none pending.
async fn sealed(client: &tokio_postgres::Client, n: i64) {
    for _ in 0..600 {
        if chained_and_pending(client).await == (n, 0) {
            return;
        }
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    panic!(
        "not sealed: (chained, pending) = {:?}",
        chained_and_pending(client).await
    );
}

/// An act on PostgreSQL does not wait for the chain: with the chain's lock
/// held elsewhere (a sealer or a reader of the trail stuck), submissions,
/// an approval, a token and a definition still complete, their entries
/// pending; once it is let go the sealer chains them unasked, in the acts'
/// order. Entries a replica left pending when it died are chained by
/// another, and verify.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_acts_do_not_wait_for_the_chain() {
    let db = pg::TestDb::create().await;
    let watch = db.client().await;
    let mut holder = db.client().await;
    let a = PostgresStore::open(&db.url).await.unwrap();
    let first = calibration("SEAL-1", "2026-04-01T00:00:00Z");
    a.insert_calibration(first.clone(), None).await.unwrap();
    sealed(&watch, 1).await;

    // The lock the acts used to take, held across them.
    let lock = holder.transaction().await.unwrap();
    lock.batch_execute("LOCK TABLE audit IN EXCLUSIVE MODE")
        .await
        .unwrap();
    let acts = async {
        let second = calibration("SEAL-1", "2026-05-01T00:00:00Z");
        a.insert_calibration(second.clone(), None).await.unwrap();
        let approve = approval();
        assert!(matches!(
            a.sign(first.id, approve).await.unwrap(),
            Signed::Done(..)
        ));
        a.put_sensor_type(super::sensor_type("NAV", 365), admin(), Precondition::Any)
            .await
            .unwrap();
        second
    };
    let second = tokio::time::timeout(std::time::Duration::from_secs(60), acts)
        .await
        .expect("the acts waited for the chain's lock");
    assert_eq!(chained_and_pending(&watch).await, (1, 3));
    lock.rollback().await.unwrap();
    sealed(&watch, 4).await;
    let actions: Vec<(String, String)> = watch
        .query("SELECT action, object FROM audit ORDER BY seq", &[])
        .await
        .unwrap()
        .iter()
        .map(|r| (r.get(0), r.get(1)))
        .collect();
    let cal = |id: uuid::Uuid| format!("calibrations/{id}");
    assert_eq!(
        actions,
        [
            ("calibration.submitted".into(), cal(first.id)),
            ("calibration.submitted".into(), cal(second.id)),
            ("calibration.approve".into(), cal(first.id)),
            ("sensor_type.put".into(), "sensor-types/NAV".into()),
        ]
    );

    // A replica that dies with entries pending: another chains them.
    let lock = holder.transaction().await.unwrap();
    lock.batch_execute("LOCK TABLE audit IN EXCLUSIVE MODE")
        .await
        .unwrap();
    let third = calibration("SEAL-2", "2026-06-01T00:00:00Z");
    a.insert_calibration(third, None).await.unwrap();
    // Its sealer, woken by the commit, waits for the lock: cut it off as
    // the replica dies.
    let me: i32 = lock
        .query_one("SELECT pg_backend_pid()", &[])
        .await
        .unwrap()
        .get(0);
    let waiting = "SELECT pid FROM pg_stat_activity WHERE $1 = ANY(pg_blocking_pids(pid))";
    for _ in 0..600 {
        if !watch.query(waiting, &[&me]).await.unwrap().is_empty() {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    drop(a);
    watch
        .execute(
            &format!("SELECT pg_terminate_backend(pid) FROM ({waiting}) w"),
            &[&me],
        )
        .await
        .unwrap();
    tokio::time::sleep(std::time::Duration::from_secs(1)).await;
    assert_eq!(chained_and_pending(&watch).await, (4, 1));
    lock.rollback().await.unwrap();
    let b = PostgresStore::open(&db.url).await.unwrap();
    sealed(&watch, 5).await;
    let v = verify(&b).await.unwrap();
    assert_eq!((v.head_seq, v.calibrations, v.unsealed), (5, 3, 0));
    b.close().await;
}
