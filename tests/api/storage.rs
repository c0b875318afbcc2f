//! A failing database is a retryable 503, and the service recovers by itself.

use std::time::Duration;

use reqwest::StatusCode;

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

#[tokio::test]
async fn a_missing_database_is_503_until_it_returns() {
    let app = TestApp::spawn(Sqlite).await;
    app.submit(ADMIN, &submission("D-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let aside = app.db_path().with_extension("aside");
    std::fs::rename(app.db_path(), &aside).unwrap();

    let res = app.get("/v1/sensors", ADMIN).await;
    assert!(res.headers().contains_key("retry-after"));
    problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
    let res = app
        .post(
            "/v1/calibrations",
            ADMIN,
            &submission("D-1", "2026-01-02T00:00:00Z", 4),
        )
        .await;
    problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
    let res = app.client.get(app.url("/readyz")).send().await.unwrap();
    problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
    assert!(
        !app.db_path().exists(),
        "a missing database must not be silently recreated"
    );

    std::fs::rename(&aside, app.db_path()).unwrap();
    assert_eq!(
        app.client
            .get(app.url("/readyz"))
            .send()
            .await
            .unwrap()
            .status(),
        StatusCode::OK
    );
    app.submit(ADMIN, &submission("D-1", "2026-01-02T00:00:00Z", 4))
        .await;
    let s: serde_json::Value = app
        .get("/v1/sensors/D-1", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(s["calibration_count"], 2);
}

#[tokio::test]
async fn a_locked_database_is_503_until_the_lock_is_released() {
    let app = TestApp::spawn(Sqlite).await;
    let locker = rusqlite::Connection::open(app.db_path()).unwrap();
    locker.execute_batch("BEGIN EXCLUSIVE").unwrap();

    let res = app
        .post(
            "/v1/calibrations",
            ADMIN,
            &submission("L-1", "2026-01-01T00:00:00Z", 4),
        )
        .await;
    problem(res, StatusCode::SERVICE_UNAVAILABLE).await;

    locker.execute_batch("COMMIT").unwrap();
    drop(locker);
    let body = submission("L-1", "2026-01-01T00:00:00Z", 4);
    eventually(
        Duration::from_secs(10),
        "the submission to be stored",
        || async {
            let res = app.post("/v1/calibrations", ADMIN, &body).await;
            (res.status() == StatusCode::CREATED).then_some(())
        },
    )
    .await;
}
