//! Authorship survives supersession and reprocessing (issue 42 item 5): the
//! person who submitted a measurement may not approve or reject it, nor a
//! correction or a reprocessing of it, nor may whoever submitted the
//! correction; a third reviewer may.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

fn paper() -> Value {
    serde_json::from_str(include_str!("../../examples/paper-table1.json")).unwrap()
}

/// A reviewer token held by `holder`: its secret and its id.
async fn reviewer(app: &TestApp, holder: &str) -> (String, String) {
    let res = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "reviewer", "holder": holder}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let v: Value = res.json().await.unwrap();
    (
        v["token"].as_str().unwrap().to_owned(),
        v["id"].as_str().unwrap().to_owned(),
    )
}

async fn approve(app: &TestApp, token: &str, id: &Value) -> StatusCode {
    app.post(
        &format!("/v1/calibrations/{}/review", id.as_str().unwrap()),
        token,
        &json!({"decision": "approve"}),
    )
    .await
    .status()
}

#[rstest]
#[tokio::test]
async fn the_author_may_not_approve_a_correction_of_their_measurement(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let (ann, _) = reviewer(&app, "Ann Author").await;
    let (rita, _) = reviewer(&app, "Rita Corrector").await;
    let (bob, _) = reviewer(&app, "Bob Third").await;
    let a = app.submit(&ann, &paper()).await["id"].clone();
    assert_eq!(approve(&app, &ann, &a).await, StatusCode::FORBIDDEN);
    // Rita corrects it (another sensor id): the replacement is Rita's
    // submission, but Ann's measurement.
    let mut corrected = paper();
    corrected["sensor_id"] = json!("PAPER-CORRECTED");
    let res = app
        .post(
            &format!(
                "/v1/calibrations/{}/supersede?reason=wrong%20sensor%20id",
                a.as_str().unwrap()
            ),
            &rita,
            &corrected,
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let b = res.json::<Value>().await.unwrap()["id"].clone();
    let refused = app
        .post(
            &format!("/v1/calibrations/{}/review", b.as_str().unwrap()),
            &ann,
            &json!({"decision": "approve"}),
        )
        .await;
    let p = problem(refused, StatusCode::FORBIDDEN).await;
    assert!(p["detail"].as_str().unwrap().contains("Ann Author"), "{p}");
    assert_eq!(approve(&app, &rita, &b).await, StatusCode::FORBIDDEN);
    assert_eq!(approve(&app, &bob, &b).await, StatusCode::OK);
}

/// Reprocessing a calibration Ann submitted (stored by an older method, so
/// reprocessing supersedes it): Rita's replacement stays Ann's measurement.
#[rstest]
#[tokio::test]
async fn the_author_may_not_approve_a_reprocessing_of_their_measurement(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let (ann, ann_id) = reviewer(&app, "Ann Author").await;
    let (rita, _) = reviewer(&app, "Rita Reprocessor").await;
    let (bob, _) = reviewer(&app, "Bob Third").await;
    let body = paper();
    let truth: Value = app
        .post("/v1/identify", ADMIN, &body)
        .await
        .json()
        .await
        .unwrap();
    let old_id = crate::older::store_by_an_older_method(&app, &body, &truth, &ann_id).await;
    let old = json!(old_id.to_string());
    assert_eq!(approve(&app, &ann, &old).await, StatusCode::FORBIDDEN);
    let res = app
        .post(
            &format!("/v1/calibrations/{old_id}/reprocess"),
            &rita,
            &json!({}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["outcome"], "superseded");
    let new = r["replacement_id"].clone();
    assert_eq!(approve(&app, &ann, &new).await, StatusCode::FORBIDDEN);
    assert_eq!(approve(&app, &rita, &new).await, StatusCode::FORBIDDEN);
    assert_eq!(approve(&app, &bob, &new).await, StatusCode::OK);
}
