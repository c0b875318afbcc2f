//! The database becoming unavailable and coming back, on either engine (the
//! SQLite file moved away, the PostgreSQL server unreachable): every call
//! that needs it is a 503 with Retry-After, `/readyz` fails while `/healthz`
//! does not, nothing acknowledged is lost, and the service recovers by
//! itself.

use std::time::Duration;

use reqwest::StatusCode;
use serde_json::Value;

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

#[rstest]
#[tokio::test]
async fn an_unavailable_database_is_503_and_the_service_recovers_by_itself(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let reader = app.token("reader", None).await;
    let first = app
        .submit(ADMIN, &submission("OUT-1", "2026-01-01T00:00:00Z", 4))
        .await;
    app.db().cut();

    for res in [
        app.get("/v1/sensors", &reader).await,
        app.get("/v1/sensors/OUT-1", &reader).await,
        app.post(
            "/v1/calibrations",
            ADMIN,
            &submission("OUT-1", "2026-01-02T00:00:00Z", 4),
        )
        .await,
    ] {
        assert!(res.headers().contains_key("retry-after"));
        problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
    }
    let ready = app.client.get(app.url("/readyz")).send().await.unwrap();
    problem(ready, StatusCode::SERVICE_UNAVAILABLE).await;
    let alive = app.client.get(app.url("/healthz")).send().await.unwrap();
    assert_eq!(alive.status(), StatusCode::OK, "the process itself is fine");

    app.db().restore();
    eventually(Duration::from_secs(15), "/readyz to pass again", || async {
        let res = app.client.get(app.url("/readyz")).send().await.unwrap();
        (res.status() == StatusCode::OK).then_some(())
    })
    .await;
    let path = format!("/v1/calibrations/{}", first["id"].as_str().unwrap());
    let again: Value = app.get(&path, &reader).await.json().await.unwrap();
    assert_eq!(
        again, first,
        "the acknowledged calibration, as acknowledged"
    );
    app.submit(ADMIN, &submission("OUT-1", "2026-01-02T00:00:00Z", 4))
        .await;
    let s: Value = app
        .get("/v1/sensors/OUT-1", &reader)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(s["calibration_count"], 2);
}
