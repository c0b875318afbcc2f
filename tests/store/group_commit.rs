//! PostgreSQL's group commit (`src/store/postgres/writer.rs`), driven
//! deterministically: a plain connection holds the row lock of one sensor,
//! so the writer's batch that writes it waits, while the next writes queue
//! behind it and then share one transaction.

use std::sync::Arc;

use super::{calibration, key, pg, until};
use accelcal::store::Precondition;
use accelcal::store::prelude::*;
use accelcal::store::{
    AuditQuery, IdempotencyKey, NewCalibration, Store, StoreError, Stored, postgres::PostgresStore,
    sqlite::SqliteStore,
};
use accelcal_core::decision::Verdict;
use tokio::task::JoinHandle;

type Answer = JoinHandle<Result<Stored, StoreError>>;

fn write(s: &Arc<PostgresStore>, c: NewCalibration, k: Option<IdempotencyKey>) -> Answer {
    let s = s.clone();
    tokio::spawn(async move { s.insert_calibration(c, k).await })
}

/// The writer, held: its current batch writes sensor `HOLD`, whose row
/// another connection has locked.
struct Held {
    blocker: tokio_postgres::Client,
    first: Answer,
}

/// Locks sensor `HOLD` from another connection and starts a write of it;
/// returns once that write's batch is waiting for the lock.
async fn hold(db: &pg::TestDb, s: &Arc<PostgresStore>) -> Held {
    s.insert_calibration(calibration("HOLD", "2026-01-01T00:00:00Z"), None)
        .await
        .unwrap();
    let blocker = db.client().await;
    blocker
        .batch_execute("BEGIN; SELECT 1 FROM sensors WHERE sensor_id = 'HOLD' FOR UPDATE")
        .await
        .unwrap();
    let first = write(s, calibration("HOLD", "2026-02-01T00:00:00Z"), None);
    let watcher = db.client().await;
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    loop {
        let waiting: i64 = watcher
            .query_one(
                "SELECT count(*) FROM pg_stat_activity \
                 WHERE datname = current_database() AND wait_event_type = 'Lock'",
                &[],
            )
            .await
            .unwrap()
            .get(0);
        if waiting > 0 {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the writer never waited"
        );
        tokio::time::sleep(std::time::Duration::from_millis(2)).await;
    }
    Held { blocker, first }
}

impl Held {
    /// Releases the lock; the held batch commits, then the queued one runs.
    async fn release(self) {
        self.blocker.batch_execute("COMMIT").await.unwrap();
        assert_eq!(self.first.await.unwrap().unwrap(), Stored::New);
    }
}

/// Queues `writes` behind a held batch, then lets them run as one.
async fn one_batch(
    db: &pg::TestDb,
    s: &Arc<PostgresStore>,
    writes: Vec<(NewCalibration, Option<IdempotencyKey>)>,
) -> Vec<Result<Stored, StoreError>> {
    let held = hold(db, s).await;
    let n = writes.len();
    let mut answers = Vec::new();
    for (c, k) in writes {
        answers.push(write(s, c, k));
        // One at a time, so the order of the queue is the order given.
        let queued = answers.len();
        until(|| s.writer().queued() == queued, "the write to queue").await;
    }
    assert_eq!(s.writer().queued(), n);
    held.release().await;
    let mut out = Vec::new();
    for a in answers {
        out.push(a.await.unwrap());
    }
    out
}

async fn count(db: &pg::TestDb, sql: &str) -> i64 {
    db.client().await.query_one(sql, &[]).await.unwrap().get(0)
}

/// Twenty writes queued together commit as one transaction, each answered
/// only after that commit, and each sensor's summary counts its own.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_queued_writes_commit_as_one_batch() {
    let db = pg::TestDb::create().await;
    let s = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let writes = (0..20)
        .map(|i| {
            let day = 1 + i / 4;
            let c = calibration(
                &format!("S-{}", i % 4),
                &format!("2026-03-{day:02}T00:00:00Z"),
            );
            (c, None)
        })
        .collect::<Vec<_>>();
    let ids: Vec<_> = writes.iter().map(|(c, _)| c.id).collect();
    let (batches, stored) = s.writer().counts().get();
    let answers = one_batch(&db, &s, writes).await;
    for a in answers {
        assert_eq!(a.unwrap(), Stored::New);
    }
    // The holding sensor's first write, the held write's batch, then one
    // batch of twenty.
    assert_eq!(s.writer().counts().get(), (batches + 3, stored + 22));
    assert_eq!(
        count(
            &db,
            "SELECT count(*) FROM calibrations WHERE sensor_id LIKE 'S-%'"
        )
        .await,
        20
    );
    for i in 0..4 {
        let sensor = s
            .sensor(format!("S-{i}"), super::now())
            .await
            .unwrap()
            .unwrap();
        assert_eq!(sensor.calibration_count, 5);
        // The latest is the one performed last (day 5), whatever the order
        // the batch wrote them in.
        assert_eq!(sensor.latest.id, ids[16 + i]);
    }
}

/// A write the database refuses fails alone: the batch is rolled back and
/// each of its writes stored in a transaction of its own. Two writes of one
/// idempotency key in one batch store one calibration, with or without a
/// refused write beside them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_a_refused_write_fails_alone_in_its_batch() {
    let db = pg::TestDb::create().await;
    let s = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    for refusing in [true, false] {
        let mut writes: Vec<_> = (0..6)
            .map(|i| (calibration(&format!("G-{i}"), "2026-04-01T00:00:00Z"), None))
            .collect();
        let twice = key(if refusing { "k-a" } else { "k-b" }, 3);
        let first = calibration("K-1", "2026-04-01T00:00:00Z");
        let second = calibration("K-2", "2026-04-01T00:00:00Z");
        let first_id = first.id;
        writes.insert(2, (first, Some(twice.clone())));
        writes.insert(4, (second, Some(twice)));
        if refusing {
            // Names a sensor type that does not exist: the sensor's row
            // refers to it, and PostgreSQL refuses.
            let mut bad = calibration("BAD", "2026-04-01T00:00:00Z");
            bad.sensor_type = Some("no-such-type".into());
            bad.assigns_type = true;
            writes.insert(3, (bad, None));
        }
        let answers = one_batch(&db, &s, writes).await;
        let mut answers = answers.into_iter();
        for (i, a) in answers.by_ref().enumerate() {
            match (i, refusing) {
                (2, _) => assert_eq!(a.unwrap(), Stored::New),
                (3, true) => assert!(matches!(a, Err(StoreError::Constraint(_))), "{a:?}"),
                (4, false) | (5, true) => assert_eq!(a.unwrap(), Stored::Existing(first_id)),
                _ => assert_eq!(a.unwrap(), Stored::New),
            }
        }
        assert_eq!(
            count(
                &db,
                "SELECT count(*) FROM calibrations WHERE sensor_id = 'K-2'"
            )
            .await,
            0
        );
        assert_eq!(
            count(
                &db,
                "SELECT count(*) FROM calibrations WHERE sensor_id = 'BAD'"
            )
            .await,
            0
        );
    }
    assert_eq!(
        count(
            &db,
            "SELECT count(*) FROM calibrations WHERE sensor_id LIKE 'G-%'"
        )
        .await,
        12
    );
    assert_eq!(
        count(
            &db,
            "SELECT count(*) FROM sensors WHERE sensor_id LIKE 'G-%'"
        )
        .await,
        6
    );
}

/// A full queue refuses at once (503 upstream); what was queued is stored
/// once the database frees up.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_a_full_queue_refuses_instead_of_waiting() {
    let db = pg::TestDb::create().await;
    let s = Arc::new(PostgresStore::open_with_queue(&db.url, 2).await.unwrap());
    let held = hold(&db, &s).await;
    let queued = vec![
        write(&s, calibration("Q-1", "2026-05-01T00:00:00Z"), None),
        write(&s, calibration("Q-2", "2026-05-01T00:00:00Z"), None),
    ];
    until(|| s.writer().queued() == 2, "two writes to queue").await;
    match s
        .insert_calibration(calibration("Q-3", "2026-05-01T00:00:00Z"), None)
        .await
    {
        Err(StoreError::Overloaded(2)) => {}
        other => panic!("expected Overloaded(2), got {other:?}"),
    }
    held.release().await;
    for q in queued {
        assert_eq!(q.await.unwrap().unwrap(), Stored::New);
    }
    assert_eq!(
        count(
            &db,
            "SELECT count(*) FROM calibrations WHERE sensor_id LIKE 'Q-%'"
        )
        .await,
        2
    );
}

/// One planned write: sensor, performed_at, type named, whether it assigns
/// it, verdict, due date, idempotency key.
type Planned = (
    &'static str,
    &'static str,
    Option<&'static str>,
    bool,
    Option<Verdict>,
    Option<&'static str>,
    Option<&'static str>,
);

/// A batch stores what the same writes stored one at a time store: every
/// column of every calibration, and each sensor's summary — count, first
/// date, latest calibration by `(performed_at, id)` with its verdict and due
/// date, the last type assigned — with writes out of date order, a tie on
/// `performed_at`, types named with and without assigning them, a key
/// completed before the batch and a key completed by it. The reference is
/// the SQLite engine, written one write at a time.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_a_batch_stores_what_one_at_a_time_stores() {
    let db = pg::TestDb::create().await;
    let pg = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let dir = tempfile::tempdir().unwrap();
    let lite = SqliteStore::open(dir.path().join("reference.db")).unwrap();
    let stores: [&dyn Store; 2] = [&*pg, &lite];
    let done = calibration("F-1", "2026-06-01T00:00:00Z");
    for s in stores {
        for t in ["NAV", "GYR"] {
            assert!(
                s.put_sensor_type(
                    super::sensor_type(t, 365),
                    super::admin(),
                    Precondition::Any
                )
                .await
                .unwrap()
                .created()
            );
        }
        let first = s
            .insert_calibration(done.clone(), Some(key("done", 1)))
            .await
            .unwrap();
        assert_eq!(first, Stored::New);
    }

    let plan: [Planned; 12] = [
        (
            "F-1",
            "2026-06-03T00:00:00Z",
            Some("NAV"),
            true,
            Some(Verdict::Pass),
            Some("2027-06-03T00:00:00Z"),
            None,
        ),
        (
            "F-1",
            "2026-06-02T00:00:00Z",
            Some("GYR"),
            true,
            Some(Verdict::Fail),
            None,
            None,
        ),
        (
            "F-2",
            "2026-06-05T00:00:00Z",
            None,
            false,
            None,
            None,
            Some("fresh"),
        ),
        (
            "F-1",
            "2026-05-01T00:00:00Z",
            None,
            false,
            None,
            None,
            Some("done"),
        ),
        (
            "F-2",
            "2026-06-05T00:00:00Z",
            Some("NAV"),
            false,
            Some(Verdict::Conditional),
            None,
            None,
        ),
        (
            "F-3",
            "2026-06-09T00:00:00Z",
            Some("GYR"),
            true,
            Some(Verdict::Pass),
            Some("2027-06-09T00:00:00Z"),
            None,
        ),
        ("F-2", "2026-06-04T00:00:00Z", None, false, None, None, None),
        ("F-3", "2026-06-08T00:00:00Z", None, false, None, None, None),
        ("F-1", "2026-06-03T00:00:00Z", None, false, None, None, None),
        (
            "F-3",
            "2026-06-07T00:00:00Z",
            Some("NAV"),
            true,
            None,
            None,
            None,
        ),
        ("F-1", "2026-05-30T00:00:00Z", None, false, None, None, None),
        ("F-2", "2026-06-01T00:00:00Z", None, false, None, None, None),
    ];
    let writes: Vec<(NewCalibration, Option<IdempotencyKey>)> = plan
        .iter()
        .map(|&(sensor, at, named, assigns, verdict, due, k)| {
            let mut c = calibration(sensor, at);
            c.sensor_type = named.map(Into::into);
            c.assigns_type = assigns;
            c.verdict = verdict;
            c.due_at = due.map(super::t);
            // Not "done"'s body: its hash is "done"'s, as a retry's is.
            (c, k.map(|k| key(k, 1)))
        })
        .collect();

    let batched = one_batch(&db, &pg, writes.clone()).await;
    let mut one_by_one = Vec::new();
    for (c, k) in writes.clone() {
        one_by_one.push(lite.insert_calibration(c, k).await);
    }
    for (i, (b, o)) in batched.into_iter().zip(one_by_one).enumerate() {
        let expected = if i == 3 {
            Stored::Existing(done.id)
        } else {
            Stored::New
        };
        assert_eq!(b.unwrap(), expected, "batched write {i}");
        assert_eq!(o.unwrap(), expected, "write {i} alone");
    }

    for (i, (c, _)) in writes.iter().enumerate() {
        let got = pg.calibration_summary(c.id).await.unwrap();
        if i == 3 {
            assert_eq!(got, None, "an answered key's write was stored");
            continue;
        }
        assert_eq!(got, lite.calibration_summary(c.id).await.unwrap(), "{i}");
        assert_eq!(
            pg.calibration_result(c.id).await.unwrap(),
            Some(c.result.clone())
        );
        let sub = pg.submission(c.id).await.unwrap().unwrap();
        assert_eq!(sub.body, c.submission, "{i}");
    }
    for sensor in ["F-1", "F-2", "F-3"] {
        let b = pg.sensor(sensor.into(), super::now()).await.unwrap();
        let o = lite.sensor(sensor.into(), super::now()).await.unwrap();
        assert_eq!(b, o, "{sensor}");
    }
    // And by hand, what the summaries must be.
    let f1 = pg
        .sensor("F-1".into(), super::now())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(f1.calibration_count, 5);
    assert_eq!(f1.first_performed_at, super::t("2026-05-30T00:00:00Z"));
    // Two performed on 06-03: the greater id is the latest.
    let (latest, verdict) = if writes[8].0.id > writes[0].0.id {
        (writes[8].0.id, None)
    } else {
        (writes[0].0.id, Some(Verdict::Pass))
    };
    assert_eq!(f1.latest.id, latest);
    assert_eq!(f1.latest_verdict, verdict);
    assert_eq!(f1.sensor_type.as_deref(), Some("GYR"));
    let f2 = pg
        .sensor("F-2".into(), super::now())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(f2.calibration_count, 4);
    let (latest, verdict) = if writes[4].0.id > writes[2].0.id {
        (writes[4].0.id, Some(Verdict::Conditional))
    } else {
        (writes[2].0.id, None)
    };
    assert_eq!(f2.latest.id, latest);
    assert_eq!(f2.latest_verdict, verdict);
    assert_eq!(f2.sensor_type, None);
    let f3 = pg
        .sensor("F-3".into(), super::now())
        .await
        .unwrap()
        .unwrap();
    assert_eq!(f3.calibration_count, 3);
    assert_eq!(f3.latest.id, writes[5].0.id);
    assert_eq!(f3.due_at, Some(super::t("2027-06-09T00:00:00Z")));
    assert_eq!(f3.sensor_type.as_deref(), Some("NAV"));
    // Each stored calibration's entry says what storing it did as the
    // batch left its sensor's row — the latest served, the others
    // nothing — and the rest of its change is what a write alone records.
    for (i, (c, _)) in writes.iter().enumerate() {
        if i == 3 {
            continue;
        }
        let q = || AuditQuery {
            object: Some(format!("calibrations/{}", c.id)),
            limit: 10,
            ..AuditQuery::default()
        };
        let (batched, alone) = (pg.audit(q()).await.unwrap(), lite.audit(q()).await.unwrap());
        let ([b], [o]) = (&batched[..], &alone[..]) else {
            panic!("{i}: {batched:?} {alone:?}");
        };
        assert_eq!(
            (&b.action, &b.actor, b.at),
            (&o.action, &o.actor, o.at),
            "{i}"
        );
        let latest = pg
            .sensor(c.sensor_id.clone(), super::now())
            .await
            .unwrap()
            .unwrap()
            .latest
            .id;
        let not_rejected = if latest == c.id {
            serde_json::json!({"changed": true, "calibration_id": c.id.to_string()})
        } else {
            serde_json::json!({"changed": false})
        };
        let mut b: serde_json::Value = serde_json::from_str(&b.change).unwrap();
        let mut o: serde_json::Value = serde_json::from_str(&o.change).unwrap();
        assert_eq!(
            b["coefficients"],
            serde_json::json!({"not_rejected": not_rejected, "approved_only": {"changed": false}}),
            "{i}"
        );
        b["coefficients"].take();
        o["coefficients"].take();
        assert_eq!(b, o, "{i}");
    }
    // The key completed by the batch answers its retry.
    let retry = calibration("F-2", "2026-06-05T00:00:00Z");
    assert_eq!(
        pg.insert_calibration(retry, Some(key("fresh", 1)))
            .await
            .unwrap(),
        Stored::Existing(writes[2].0.id)
    );
}
