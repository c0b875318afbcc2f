//! Three replicas on one PostgreSQL database, as behind a load balancer:
//! submitters spread over them, every submission sent to two replicas at
//! once under one idempotency key, and one replica killed with SIGKILL
//! mid-load. Afterwards every acknowledged calibration is present and
//! identical on every live replica, each key stored exactly one record, and
//! the sensors' counts equal their rows.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use reqwest::StatusCode;
use serde_json::{Value, json};

use crate::db::Db;
use accelcal_testkit::process::{ADMIN, Server};

fn submission(sensor: &str, n: u64) -> Value {
    let runs: Vec<Value> = (0..4u64)
        .map(|j| {
            let e = |p: u64| 1e-6 * (n as f64 * 0.41 + j as f64 * 1.7 + p as f64 * 2.3).sin();
            json!({"readings": [[0.0062 + e(0)], [1.216 + e(1)], [-0.0062 + e(2)], [-1.216 + e(3)]]})
        })
        .collect();
    json!({
        "sensor_id": sensor,
        "performed_at": format!("2026-02-01T{:02}:{:02}:{:02}Z", n / 3600 % 24, n / 60 % 60, n % 60),
        "positions": [{"angle_deg": 0}, {"angle_deg": 90}, {"angle_deg": 180}, {"angle_deg": 270}],
        "runs": runs,
    })
}

#[derive(Default)]
struct Ledger {
    /// id → the 201 body.
    acked: BTreeMap<String, Value>,
    /// Keys no replica acknowledged (in flight at the kill, or only 409s).
    unknown: Vec<(String, Value)>,
    /// Keys answered 201 by both replicas (one stored, one replayed).
    both: usize,
}

async fn send(
    client: &reqwest::Client,
    base: &str,
    key: &str,
    body: &Value,
) -> Option<(StatusCode, Value, bool)> {
    let res = client
        .post(format!("{base}/v1/calibrations"))
        .bearer_auth(ADMIN)
        .header("idempotency-key", key)
        .json(body)
        .send()
        .await
        .ok()?;
    let status = res.status();
    let replayed = res.headers().contains_key("idempotent-replayed");
    let body = res.json::<Value>().await.ok()?;
    Some((status, body, replayed))
}

async fn submitter(
    w: u64,
    bases: Arc<Vec<String>>,
    dead: Arc<Vec<AtomicBool>>,
    until: Instant,
    ledger: Arc<Mutex<Ledger>>,
) {
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(10))
        .build()
        .unwrap();
    let mut n = w * 1_000_000;
    while Instant::now() < until {
        n += 1;
        let key = format!("RK-{n}");
        // Four sensors shared by all submitters: replicas contend on each row.
        let body = submission(&format!("RS-{}", n % 4), n);
        let alive: Vec<usize> = (0..bases.len())
            .filter(|&i| !dead[i].load(Ordering::SeqCst))
            .collect();
        let a = alive[(n as usize) % alive.len()];
        let b = alive[(n as usize + 1) % alive.len()];
        let (x, y) = tokio::join!(
            send(&client, &bases[a], &key, &body),
            send(&client, &bases[b], &key, &body)
        );
        let mut l = ledger.lock().unwrap();
        let created: Vec<(Value, bool)> = [x, y]
            .into_iter()
            .flatten()
            .filter_map(|(status, v, replayed)| {
                assert!(
                    status == StatusCode::CREATED || status == StatusCode::CONFLICT,
                    "{key}: {status} {v}"
                );
                (status == StatusCode::CREATED).then_some((v, replayed))
            })
            .collect();
        match created.as_slice() {
            [] => l.unknown.push((key, body)),
            [(v, _)] => {
                l.acked
                    .insert(v["id"].as_str().unwrap().to_owned(), v.clone());
            }
            [(v1, r1), (v2, r2)] => {
                assert_eq!(
                    v1, v2,
                    "{key}: two replicas answered two different calibrations"
                );
                assert!(r1 ^ r2, "{key}: exactly one of the two answers is a replay");
                l.both += 1;
                l.acked
                    .insert(v1["id"].as_str().unwrap().to_owned(), v1.clone());
            }
            _ => unreachable!(),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn three_replicas_share_one_database_through_a_kill() {
    let db = Db::Postgres(accelcal_testkit::pg::TestDb::create().await);
    let flags = ["--request-timeout", "2"];
    let mut servers: Vec<Server> = Vec::new();
    for _ in 0..3 {
        servers.push(Server::start_with(db.url(), &flags, "info"));
    }
    let bases = Arc::new(servers.iter().map(|s| s.base.clone()).collect::<Vec<_>>());
    let dead = Arc::new((0..3).map(|_| AtomicBool::new(false)).collect::<Vec<_>>());
    let ledger = Arc::new(Mutex::new(Ledger::default()));
    let until = Instant::now() + Duration::from_secs(4);
    let tasks: Vec<_> = (0..6)
        .map(|w| {
            tokio::spawn(submitter(
                w,
                bases.clone(),
                dead.clone(),
                until,
                ledger.clone(),
            ))
        })
        .collect();
    tokio::time::sleep(Duration::from_millis(1500)).await;
    dead[2].store(true, Ordering::SeqCst);
    servers[2].kill9();
    for t in tasks {
        t.await.unwrap();
    }
    db.check().await;

    let (acked, unknown, both) = {
        let l = ledger.lock().unwrap();
        (l.acked.clone(), l.unknown.clone(), l.both)
    };
    assert!(acked.len() > 100, "only {} acknowledged", acked.len());
    let client = reqwest::Client::new();
    // Every acknowledged calibration, as acknowledged, from every live replica.
    for base in &bases[..2] {
        for (id, body) in &acked {
            let res = client
                .get(format!("{base}/v1/calibrations/{id}"))
                .bearer_auth(ADMIN)
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), StatusCode::OK, "{id} missing at {base}");
            assert_eq!(
                &res.json::<Value>().await.unwrap(),
                body,
                "{id} differs at {base}"
            );
        }
    }
    // Keys nobody acknowledged: retried, each is stored once (or was already).
    let before = db.number("SELECT count(*) FROM calibrations").await;
    let mut replayed = 0;
    for (key, body) in &unknown {
        let deadline = Instant::now() + Duration::from_secs(30);
        let answer = loop {
            let (status, v, again) = send(&client, &bases[(key.len()) % 2], key, body)
                .await
                .unwrap();
            if status != StatusCode::CONFLICT {
                break (status, v, again);
            }
            assert!(Instant::now() < deadline, "{key} stayed in flight");
            tokio::time::sleep(Duration::from_millis(200)).await;
        };
        assert_eq!(answer.0, StatusCode::CREATED, "{key}: {}", answer.1);
        replayed += usize::from(answer.2);
    }
    let after = db.number("SELECT count(*) FROM calibrations").await;
    assert_eq!(after - before, (unknown.len() - replayed) as i64);
    assert_eq!(
        after,
        (acked.len() + unknown.len()) as i64,
        "one calibration per key, no more, no less"
    );
    db.check().await;
    // A sensor's summary on one replica follows another replica's commit
    // once the notification has arrived (its cache): poll, with a deadline.
    let deadline = Instant::now() + Duration::from_secs(10);
    let counts: Vec<i64> = loop {
        let mut v = Vec::new();
        for s in 0..4 {
            let res: Value = client
                .get(format!("{}/v1/sensors/RS-{s}", bases[0]))
                .bearer_auth(ADMIN)
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap();
            v.push(res["calibration_count"].as_i64().unwrap());
        }
        if v.iter().sum::<i64>() == after || Instant::now() >= deadline {
            break v;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert_eq!(
        counts.iter().sum::<i64>(),
        after,
        "sensor counts equal the rows"
    );
    eprintln!(
        "3 replicas, one killed: {} acknowledged ({both} by both replicas), {} retried after ({replayed} had been stored)",
        acked.len(),
        unknown.len()
    );
}
