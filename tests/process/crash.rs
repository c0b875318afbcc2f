//! kill -9 at random moments under concurrent submissions: every
//! acknowledged calibration survives intact, and nothing is half-written.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use reqwest::StatusCode;
use serde_json::{Value, json};

use crate::db::Db;
use accelcal_testkit::process::{ADMIN, Server};

/// A deterministic xorshift, so a failing round can be replayed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

fn submission(sensor: &str, n: u64) -> Value {
    let runs: Vec<Value> = (0..4u64)
        .map(|j| {
            let e = |p: u64| 1e-6 * (n as f64 * 0.37 + j as f64 * 1.3 + p as f64 * 2.1).sin();
            json!({"readings": [[0.0062 + e(0)], [1.216 + e(1)], [-0.0062 + e(2)], [-1.216 + e(3)]]})
        })
        .collect();
    json!({
        "sensor_id": sensor,
        "performed_at": format!("2026-01-01T00:{:02}:{:02}Z", (n / 60) % 60, n % 60),
        "positions": [{"angle_deg": 0}, {"angle_deg": 90}, {"angle_deg": 180}, {"angle_deg": 270}],
        "runs": runs,
    })
}

/// What a worker sent and what it learned.
#[derive(Default)]
struct Ledger {
    /// Acknowledged: id → the 201 body.
    acked: BTreeMap<String, Value>,
    /// Sent but not acknowledged (the server died): (key, body).
    unknown: Vec<(String, Value)>,
}

async fn worker(base: String, name: String, ledger: Arc<Mutex<Ledger>>, mut n: u64) {
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(10))
        .build()
        .unwrap();
    loop {
        n += 1;
        let key = format!("{name}-{n}");
        let body = submission(&name, n);
        let res = client
            .post(format!("{base}/v1/calibrations"))
            .bearer_auth(ADMIN)
            .header("idempotency-key", &key)
            .json(&body)
            .send()
            .await;
        let answer = match res {
            Ok(r) if r.status() == StatusCode::CREATED => r.json::<Value>().await.ok(),
            Ok(r) => panic!(
                "{key}: unexpected {}: {}",
                r.status(),
                r.text().await.unwrap_or_default()
            ),
            Err(_) => None,
        };
        let mut l = ledger.lock().unwrap();
        match answer {
            Some(v) => {
                l.acked.insert(v["id"].as_str().unwrap().to_owned(), v);
            }
            None => {
                l.unknown.push((key, body));
                return;
            }
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn acknowledged_submissions_survive_kill_9() {
    crash_rounds(Db::Sqlite(tempfile::tempdir().unwrap()), &[]).await;
}

/// On PostgreSQL a killed replica's idempotency leases are not freed by the
/// next start (other replicas may be alive): they expire. A short request
/// deadline keeps them short here.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn acknowledged_submissions_survive_kill_9_on_postgres() {
    crash_rounds(
        Db::Postgres(accelcal_testkit::pg::TestDb::create().await),
        &["--request-timeout", "2"],
    )
    .await;
}

async fn crash_rounds(db: Db, flags: &[&str]) {
    const ROUNDS: u64 = 24;
    const WORKERS: u64 = 4;
    let ledger = Arc::new(Mutex::new(Ledger::default()));
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for round in 0..ROUNDS {
        let mut server = Server::start_with(db.url(), flags, "debug");
        let tasks: Vec<_> = (0..WORKERS)
            .map(|w| {
                tokio::spawn(worker(
                    server.base.clone(),
                    format!("CR-{w}"),
                    ledger.clone(),
                    round * 100_000,
                ))
            })
            .collect();
        let delay = 20 + rng.next() % 400;
        tokio::time::sleep(Duration::from_millis(delay)).await;
        server.kill9();
        for t in tasks {
            t.await.unwrap();
        }
        db.check().await;
    }

    // After the last crash: every acknowledged calibration is there, identical.
    let server = Server::start_with(db.url(), flags, "debug");
    let client = reqwest::Client::new();
    let (acked, unknown) = {
        let l = ledger.lock().unwrap();
        (l.acked.clone(), l.unknown.clone())
    };
    assert!(
        acked.len() > ROUNDS as usize,
        "too few acknowledged submissions ({}) to mean much",
        acked.len()
    );
    for (id, body) in &acked {
        let res = client
            .get(format!("{}/v1/calibrations/{id}", server.base))
            .bearer_auth(ADMIN)
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), StatusCode::OK, "acknowledged {id} is lost");
        assert_eq!(
            &res.json::<Value>().await.unwrap(),
            body,
            "acknowledged {id} changed"
        );
    }
    // Every unacknowledged request is wholly present or wholly absent: its
    // retry (same key) is answered 201 — once a killed process's lease on the
    // key has expired, where the engine does not free it — and stores at
    // most one record.
    // SQLite: the file is the serving process's alone (`unix-excl`), so the
    // database is counted with the server stopped.
    drop(server);
    let before = db.number("SELECT count(*) FROM calibrations").await;
    let server = Server::start_with(db.url(), flags, "debug");
    let mut replayed = 0;
    for (key, body) in &unknown {
        let deadline = std::time::Instant::now() + Duration::from_secs(30);
        let res = loop {
            let res = client
                .post(format!("{}/v1/calibrations", server.base))
                .bearer_auth(ADMIN)
                .header("idempotency-key", key)
                .json(body)
                .send()
                .await
                .unwrap();
            if res.status() != StatusCode::CONFLICT {
                break res;
            }
            assert!(
                std::time::Instant::now() < deadline,
                "{key} stayed in flight"
            );
            tokio::time::sleep(Duration::from_millis(200)).await;
        };
        assert_eq!(res.status(), StatusCode::CREATED, "{key}");
        if res.headers().get("idempotent-replayed").is_some() {
            replayed += 1;
        }
    }
    drop(server);
    let after = db.number("SELECT count(*) FROM calibrations").await;
    assert_eq!(after - before, (unknown.len() - replayed) as i64);
    db.check().await;
    eprintln!(
        "{ROUNDS} kills: {} acknowledged, {} in flight at a kill ({} of them had been committed)",
        acked.len(),
        unknown.len(),
        replayed
    );
}
