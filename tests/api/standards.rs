//! Reference standards (issue 29): written by admins, read by everyone,
//! checked field by field, kept by both engines.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

fn stand() -> Value {
    serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap()
}

fn gravity() -> Value {
    json!({
        "kind": "gravity",
        "description": "Absolute gravity at the calibration bench",
        "certificate": {"number": "GRAV-2025-03", "issued_by": "Geodetic Survey", "calibrated_at": "2025-03-01T00:00:00Z"},
        "due_at": "2030-03-01T00:00:00Z",
        "gravity_m_s2": 9.80424,
        "gravity_rel_std": 2e-7,
        "traceability": "Absolute gravimeter FG5 #215, compared at ICAG-2023."
    })
}

#[rstest]
#[tokio::test]
async fn standards_are_written_by_admins_and_read_back(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let res = app.put("/v1/standards/STAND-1", ADMIN, &stand()).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let created: Value = res.json().await.unwrap();
    assert_eq!(created["standard_id"], "STAND-1");
    assert_eq!(created["kind"], "tumble_stand");
    assert_eq!(created["angle_std_arcsec"], 2.5);
    assert_eq!(created["certificate"]["number"], "CAL-2026-0117");
    assert_eq!(created["gravity_m_s2"], Value::Null);
    let res = app.put("/v1/standards/G-BENCH", ADMIN, &gravity()).await;
    assert_eq!(res.status(), StatusCode::CREATED);

    // What was answered is what is read back, one by one and listed in id
    // order, by a reader.
    let reader = app.token("reader", None).await;
    assert_eq!(
        app.get_json("/v1/standards/STAND-1", &reader).await,
        created
    );
    let list = app.get_json("/v1/standards", &reader).await;
    let ids: Vec<&str> = list["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["standard_id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, ["G-BENCH", "STAND-1"]);
    assert_eq!(list["items"][0]["gravity_m_s2"], 9.80424);

    // A recalibration of the stand replaces it: 200, the new certificate.
    let mut recalibrated = stand();
    recalibrated["certificate"]["number"] = json!("CAL-2027-0009");
    recalibrated["certificate"]["calibrated_at"] = json!("2026-11-20T00:00:00Z");
    recalibrated["due_at"] = json!("2027-11-20T00:00:00Z");
    let res = app.put("/v1/standards/STAND-1", ADMIN, &recalibrated).await;
    assert_eq!(res.status(), StatusCode::OK);
    let now = app.get_json("/v1/standards/STAND-1", &reader).await;
    assert_eq!(now["certificate"]["number"], "CAL-2027-0009");
    assert_eq!(now["due_at"], "2027-11-20T00:00:00.000000Z");

    // Only an admin writes; an unknown one is 404.
    let station = app.token("station", None).await;
    problem(
        app.put("/v1/standards/STAND-2", &station, &stand()).await,
        StatusCode::FORBIDDEN,
    )
    .await;
    let p = problem(
        app.get("/v1/standards/NOPE", &reader).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("NOPE"), "{p}");
}

/// Every problem of a standard is named: the kind's missing parameter,
/// another kind's, a due date before the calibration, an unknown field.
#[tokio::test]
async fn a_standards_problems_are_named() {
    let app = TestApp::spawn(Sqlite).await;
    let mut bad = stand();
    bad.as_object_mut().unwrap().remove("angle_std_arcsec");
    bad["gravity_rel_std"] = json!(1e-6);
    bad["due_at"] = json!("2025-01-01T00:00:00Z");
    let p = problem(
        app.put("/v1/standards/STAND-1", ADMIN, &bad).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(
        pointers(&p),
        ["/due_at", "/angle_std_arcsec", "/gravity_rel_std"]
    );
    let mut unknown = stand();
    unknown["uncertainty"] = json!(1);
    let p = problem(
        app.put("/v1/standards/STAND-1", ADMIN, &unknown).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/uncertainty"]);
    problem(
        app.put("/v1/standards/has%20space", ADMIN, &stand()).await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(
        app.get_json("/v1/standards", ADMIN).await["items"],
        json!([])
    );
}
