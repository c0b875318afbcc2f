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

/// A submission that names its standards: their uncertainties come from
/// the registry, the result and its pages list them with the certificate
/// in force; an unknown standard, one of another kind, one out of
/// calibration, or the stand's uncertainties given beside it are refused
/// with a 422 naming the role and saying why.
#[rstest]
#[tokio::test]
async fn submissions_use_standards_in_calibration_only(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    for (id, body) in [("STAND-1", stand()), ("G-BENCH", gravity())] {
        assert_eq!(
            app.put(&format!("/v1/standards/{id}"), ADMIN, &body)
                .await
                .status(),
            StatusCode::CREATED
        );
    }
    let named = |performed_at: &str, standards: Value| {
        let mut s = submission("S-STD", performed_at, 4);
        s["standards"] = standards;
        s
    };
    let ok = named(
        "2026-06-01T00:00:00Z",
        json!({"stand": "STAND-1", "gravity": "G-BENCH"}),
    );
    let result = app.submit(ADMIN, &ok).await;
    assert_eq!(
        result["stand"],
        json!({"id": "STAND-1", "angle_std_arcsec": 2.5, "gravity_rel_std": 2e-7})
    );
    let used = result["standards"].as_array().unwrap();
    assert_eq!(used.len(), 2);
    assert_eq!(
        (
            &used[0]["role"],
            &used[0]["standard_id"],
            &used[0]["certificate"]["number"]
        ),
        (&json!("stand"), &json!("STAND-1"), &json!("CAL-2026-0117"))
    );
    assert_eq!(used[1]["gravity_m_s2"], 9.80424);
    // The registry's values are in the budget exactly as the same values
    // typed into the body would be.
    let id = result["id"].as_str().unwrap();
    let stored = app.get_json(&format!("/v1/calibrations/{id}"), ADMIN).await;
    assert_eq!(stored["standards"], result["standards"]);
    assert!(
        result["uncertainty"]["terms"]["kp"]["indexing"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    let mut typed = submission("S-TYPED", "2026-06-01T00:00:00Z", 4);
    typed["stand"] = json!({"id": "STAND-1", "angle_std_arcsec": 2.5, "gravity_rel_std": 2e-7});
    let typed = app.submit(ADMIN, &typed).await;
    assert_eq!(result["uncertainty"], typed["uncertainty"]);
    assert_eq!(typed.get("standards"), None, "absent when none is named");
    // The calibration page and the certificate name the stand's
    // certificate.
    let cookie = accelcal_testkit::process::sign_in(&app.url(""), ADMIN).await;
    for page in [
        format!("/ui/calibrations/{id}"),
        format!("/ui/calibrations/{id}/certificate"),
    ] {
        let html = app
            .client
            .get(app.url(&page))
            .header("cookie", &cookie)
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        assert!(html.contains("CAL-2026-0117"), "{page}");
    }

    let app = &app;
    let refused = |body: Value| async move {
        let res = app.post("/v1/calibrations", ADMIN, &body).await;
        problem(res, StatusCode::UNPROCESSABLE_ENTITY).await
    };
    let p = refused(named(
        "2026-06-01T00:00:00Z",
        json!({"stand": "NOPE", "thermometer": "G-BENCH"}),
    ))
    .await;
    assert_eq!(pointers(&p), ["/standards/stand", "/standards/thermometer"]);
    let details: Vec<&str> = p["errors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["detail"].as_str().unwrap())
        .collect();
    assert!(details[0].contains("no standard `NOPE`"), "{details:?}");
    assert!(
        details[1].contains("is a `gravity`, not a `thermometer`"),
        "{details:?}"
    );
    let mut lapsed = stand();
    lapsed["due_at"] = json!("2026-03-01T00:00:00Z");
    assert_eq!(
        app.put("/v1/standards/STAND-OLD", ADMIN, &lapsed)
            .await
            .status(),
        StatusCode::CREATED
    );
    let p = refused(named("2026-06-01T00:00:00Z", json!({"stand": "STAND-OLD"}))).await;
    assert_eq!(pointers(&p), ["/standards/stand"]);
    let why = p["errors"][0]["detail"].as_str().unwrap();
    assert!(
        why.contains("was due on") && why.contains("CAL-2026-0117"),
        "{why}"
    );
    let p = refused(named("2025-12-01T00:00:00Z", json!({"stand": "STAND-1"}))).await;
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .contains("first calibrated on"),
        "{p}"
    );
    let mut both = ok.clone();
    both["stand"] = json!({"angle_std_arcsec": 0});
    assert_eq!(pointers(&refused(both).await), ["/stand"]);

    // Recalibrated late: a test performed under the first certificate is
    // still accepted, one performed in the gap is not, one after the new
    // calibration is, by the new certificate.
    let mut recalibrated = stand();
    recalibrated["certificate"]["number"] = json!("CAL-2027-0200");
    recalibrated["certificate"]["calibrated_at"] = json!("2026-11-20T00:00:00Z");
    recalibrated["due_at"] = json!("2027-11-20T00:00:00Z");
    let mut first = stand();
    first["due_at"] = json!("2026-09-01T00:00:00Z");
    assert_eq!(
        app.put("/v1/standards/STAND-2", ADMIN, &first)
            .await
            .status(),
        StatusCode::CREATED
    );
    assert_eq!(
        app.put("/v1/standards/STAND-2", ADMIN, &recalibrated)
            .await
            .status(),
        StatusCode::OK
    );
    let under_first = app
        .submit(
            ADMIN,
            &named("2026-08-01T00:00:00Z", json!({"stand": "STAND-2"})),
        )
        .await;
    assert_eq!(
        under_first["standards"][0]["certificate"]["number"],
        "CAL-2026-0117"
    );
    let p = refused(named("2026-10-01T00:00:00Z", json!({"stand": "STAND-2"}))).await;
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .contains("between the due date"),
        "{p}"
    );
    let under_second = app
        .submit(
            ADMIN,
            &named("2026-11-21T00:00:00Z", json!({"stand": "STAND-2"})),
        )
        .await;
    assert_eq!(
        under_second["standards"][0]["certificate"]["number"],
        "CAL-2027-0200"
    );
    let listed = app.get_json("/v1/standards/STAND-2", ADMIN).await;
    assert_eq!(
        listed["earlier"][0]["certificate"]["number"],
        "CAL-2026-0117"
    );
}
