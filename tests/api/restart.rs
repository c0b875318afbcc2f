//! Data survives a restart of the server on the same database.

use reqwest::StatusCode;
use serde_json::Value;

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

#[rstest]
#[tokio::test]
async fn restart_keeps_calibrations_and_tokens(#[values(Sqlite, Postgres)] engine: Engine) {
    let mut app = TestApp::spawn(engine).await;
    let created = app.submit(ADMIN, &paper()).await;
    let reader = app.token("reader", None).await;
    let db = app.take_database().unwrap();
    app.stop().await;

    let again = TestApp::spawn_on(&db.url).await;
    let path = format!("/v1/calibrations/{}", created["id"].as_str().unwrap());
    let res = again.get(&path, &reader).await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.json::<Value>().await.unwrap(), created);
    drop(again);
    drop(db);
}
