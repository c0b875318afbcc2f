//! `Idempotency-Key`: at most one record per key, whatever the retries.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

async fn post_with_key(app: &TestApp, token: &str, key: &str, body: &Value) -> reqwest::Response {
    app.client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(token)
        .header("idempotency-key", key)
        .json(body)
        .send()
        .await
        .unwrap()
}

async fn count(app: &TestApp, sensor: &str) -> u64 {
    let res = app.get(&format!("/v1/sensors/{sensor}"), ADMIN).await;
    if res.status() == StatusCode::NOT_FOUND {
        return 0;
    }
    res.json::<Value>().await.unwrap()["calibration_count"]
        .as_u64()
        .unwrap()
}

#[rstest]
#[tokio::test]
async fn same_key_same_body_replays_the_original(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let body = submission("I-1", "2026-01-01T00:00:00Z", 4);
    let first = post_with_key(&app, ADMIN, "k-1", &body).await;
    assert_eq!(first.status(), StatusCode::CREATED);
    assert!(first.headers().get("idempotent-replayed").is_none());
    let first: Value = first.json().await.unwrap();
    for _ in 0..3 {
        let again = post_with_key(&app, ADMIN, "k-1", &body).await;
        assert_eq!(again.status(), StatusCode::CREATED);
        assert_eq!(again.headers()["idempotent-replayed"], "true");
        assert_eq!(
            again.headers()["location"],
            format!("/v1/calibrations/{}", first["id"].as_str().unwrap()).as_str()
        );
        assert_eq!(again.json::<Value>().await.unwrap(), first);
    }
    assert_eq!(count(&app, "I-1").await, 1);
}

#[rstest]
#[tokio::test]
async fn same_key_different_body_is_refused(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let body = submission("I-2", "2026-01-01T00:00:00Z", 4);
    assert_eq!(
        post_with_key(&app, ADMIN, "k-2", &body).await.status(),
        StatusCode::CREATED
    );
    let other = submission("I-2", "2026-01-02T00:00:00Z", 4);
    let p = problem(
        post_with_key(&app, ADMIN, "k-2", &other).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(p["parameter"], "Idempotency-Key");
    assert_eq!(count(&app, "I-2").await, 1);
}

#[rstest]
#[tokio::test]
async fn keys_are_scoped_to_the_token(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let a = app.token("station", None).await;
    let b = app.token("station", None).await;
    let body = submission("I-3", "2026-01-01T00:00:00Z", 4);
    let ra: Value = post_with_key(&app, &a, "shared", &body)
        .await
        .json()
        .await
        .unwrap();
    let rb: Value = post_with_key(&app, &b, "shared", &body)
        .await
        .json()
        .await
        .unwrap();
    assert_ne!(ra["id"], rb["id"]);
    assert_eq!(count(&app, "I-3").await, 2);
}

#[rstest]
#[tokio::test]
async fn a_refused_request_does_not_burn_its_key(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let mut bad = submission("I-4", "2026-01-01T00:00:00Z", 4);
    bad["batchs"] = json!(2);
    let res = post_with_key(&app, ADMIN, "k-4", &bad).await;
    problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    // The key was released: the corrected body may use it.
    let good = submission("I-4", "2026-01-01T00:00:00Z", 4);
    assert_eq!(
        post_with_key(&app, ADMIN, "k-4", &good).await.status(),
        StatusCode::CREATED
    );
}

#[rstest]
#[tokio::test]
async fn malformed_keys_are_refused(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let body = submission("I-5", "2026-01-01T00:00:00Z", 4);
    for key in ["has space", &"x".repeat(256)] {
        let p = problem(
            post_with_key(&app, ADMIN, key, &body).await,
            StatusCode::BAD_REQUEST,
        )
        .await;
        assert_eq!(p["parameter"], "Idempotency-Key");
    }
    assert_eq!(count(&app, "I-5").await, 0);
}

/// Concurrent retries of one key: exactly one record, every answer either
/// that record or "in flight" (409, retry).
#[rstest]
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn concurrent_retries_store_exactly_one_record(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = std::sync::Arc::new(TestApp::spawn(engine).await);
    for round in 0..5 {
        let key = format!("burst-{round}");
        let body = submission(&format!("IC-{round}"), "2026-01-01T00:00:00Z", 6);
        let tasks: Vec<_> = (0..16)
            .map(|_| {
                let (app, key, body) = (app.clone(), key.clone(), body.clone());
                tokio::spawn(async move {
                    // A key stuck in flight fails the test instead of hanging it.
                    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
                    loop {
                        assert!(
                            std::time::Instant::now() < deadline,
                            "the key stayed in flight"
                        );
                        let res = post_with_key(&app, ADMIN, &key, &body).await;
                        match res.status() {
                            StatusCode::CONFLICT => {
                                assert_eq!(res.headers()["retry-after"], "1");
                                tokio::time::sleep(std::time::Duration::from_millis(20)).await;
                            }
                            StatusCode::CREATED => {
                                return res.json::<Value>().await.unwrap()["id"]
                                    .as_str()
                                    .unwrap()
                                    .to_owned();
                            }
                            other => panic!("unexpected {other}: {}", res.text().await.unwrap()),
                        }
                    }
                })
            })
            .collect();
        let mut ids = Vec::new();
        for t in tasks {
            ids.push(t.await.unwrap());
        }
        ids.dedup();
        assert_eq!(ids.len(), 1, "round {round}: {ids:?}");
        assert_eq!(count(&app, &format!("IC-{round}")).await, 1);
    }
}

/// `accelcal submit`'s client rides out an outage: it retries the 503s and,
/// thanks to the content-derived key, stores the upload once however many
/// copies run.
#[rstest]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_submit_client_retries_through_an_outage_without_duplicates(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU32, Ordering};
    let app = TestApp::spawn(engine).await;
    app.db().cut();
    let retried: Vec<Arc<AtomicU32>> = (0..3).map(|_| Arc::new(AtomicU32::new(0))).collect();
    let uploads: Vec<_> = retried
        .iter()
        .map(|count| {
            let count = count.clone();
            let u = accelcal::client::Upload {
                url: app.base.clone(),
                token: ADMIN.into(),
                body: serde_json::to_vec(&submission("RETRY-1", "2026-01-01T00:00:00Z", 4))
                    .unwrap(),
                content_type: "application/json",
                attempts: 30,
                backoff: std::time::Duration::from_millis(50),
                on_retry: Some(Arc::new(move |r: &accelcal::client::Retry| {
                    // The outage (503), or another copy holding the key (409).
                    assert!(
                        r.reason.starts_with("503") || r.reason.starts_with("409"),
                        "{}",
                        r.reason
                    );
                    count.fetch_add(1, Ordering::SeqCst);
                })),
            };
            tokio::spawn(async move { accelcal::client::submit(&u).await.unwrap() })
        })
        .collect();
    // The database comes back once every upload has met the outage.
    eventually(
        std::time::Duration::from_secs(20),
        "every upload to retry",
        || async {
            retried
                .iter()
                .all(|c| c.load(Ordering::SeqCst) > 0)
                .then_some(())
        },
    )
    .await;
    app.db().restore();
    let mut ids = Vec::new();
    for u in uploads {
        let answer = u.await.unwrap();
        assert_eq!(answer.status, StatusCode::CREATED, "{}", answer.body);
        assert!(
            answer.attempts > 1,
            "the outage should have cost at least one retry"
        );
        ids.push(serde_json::from_str::<Value>(&answer.body).unwrap()["id"].clone());
    }
    ids.dedup();
    assert_eq!(ids.len(), 1);
    assert_eq!(count(&app, "RETRY-1").await, 1);
}
