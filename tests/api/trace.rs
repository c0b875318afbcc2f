//! Reverse trace (issue 29 item 3): a standard found nonconforming puts the
//! calibrations made with it in the affected window under review, their
//! coefficients unusable until a reviewer approves them again or withdraws
//! them — on both engines.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

fn stand() -> Value {
    serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap()
}

/// `(sensor, outcome, state)` of each calibration a nonconformity lists.
fn listed(traced: &Value) -> Vec<(String, String, String)> {
    traced["calibrations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["sensor_id"].as_str().unwrap().to_owned(),
                c["outcome"].as_str().unwrap().to_owned(),
                c["state"].as_str().unwrap().to_owned(),
            )
        })
        .collect()
}

fn row(sensor: &str, outcome: &str, state: &str) -> (String, String, String) {
    (sensor.into(), outcome.into(), state.into())
}

#[rstest]
#[tokio::test]
async fn a_nonconforming_standard_holds_what_it_made(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    assert_eq!(
        app.put("/v1/standards/STAND-1", ADMIN, &stand())
            .await
            .status(),
        StatusCode::CREATED
    );
    let station = app.held_token("station", "Sam Station", Some("ST-1")).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let reader = app.token("reader", None).await;
    let submit = |sensor: &'static str, at: &'static str, named: bool| {
        let mut s = submission(sensor, at, 4);
        s["station_id"] = json!("ST-1");
        if named {
            s["standards"] = json!({"stand": "STAND-1"});
        }
        let app = &app;
        let station = station.clone();
        async move {
            app.submit(&station, &s).await["id"]
                .as_str()
                .unwrap()
                .to_owned()
        }
    };
    let a1 = submit("TR-A", "2026-02-01T00:00:00Z", true).await;
    submit("TR-A", "2026-05-01T00:00:00Z", true).await;
    let b = submit("TR-B", "2026-03-01T00:00:00Z", true).await;
    submit("TR-C", "2026-03-01T00:00:00Z", false).await;
    let d = submit("TR-D", "2026-03-10T00:00:00Z", true).await;
    let res = app
        .post(
            &format!("/v1/calibrations/{d}/withdraw"),
            &rita,
            &json!({"reason": "wrong sensor"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);

    // Found at the annual check; known good at an intermediate check: the
    // window is 02-15 … 04-15, so TR-B's calibration is held, TR-D's
    // (withdrawn) is listed and left, TR-A's (02-01, 05-01) and TR-C's (no
    // standard named) are not concerned.
    let nc = json!({"found_at": "2026-04-15T00:00:00Z",
        "last_known_good_at": "2026-02-15T00:00:00Z",
        "reason": "Indexing error of 9″ at the 90° stop."});
    let res = app
        .post("/v1/standards/STAND-1/nonconformity", ADMIN, &nc)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let first: Value = res.json().await.unwrap();
    assert_eq!(
        first["nonconformity"]["window_from"],
        "2026-02-15T00:00:00.000000Z"
    );
    assert_eq!(
        listed(&first),
        [
            row("TR-B", "under_review", "under_review"),
            row("TR-D", "unchanged", "withdrawn")
        ]
    );
    assert_eq!(first["calibrations"][0]["calibration_id"], b.as_str());

    // TR-B's coefficients are not usable while it is under review; TR-A's are.
    let coefficients = app.get_json("/v1/sensors/TR-B/coefficients", &reader).await;
    assert_eq!(coefficients["usable"], false, "{coefficients}");
    assert_eq!(coefficients["reasons"][0]["reason"], "under_review");
    problem(
        app.get("/v1/sensors/TR-B/coefficients?require=usable", &reader)
            .await,
        StatusCode::CONFLICT,
    )
    .await;
    let sensor = app.get_json("/v1/sensors/TR-B", &reader).await;
    assert_eq!(sensor["latest"]["state"], "under_review");
    let a = app.get_json("/v1/sensors/TR-A/coefficients", &reader).await;
    assert_eq!(a["usable"], true, "{a}");

    // The submitter may not approve it again; a reviewer may.
    let sam_reviewing = app.held_token("reviewer", "Sam Station", None).await;
    let res = app
        .post(
            &format!("/v1/calibrations/{b}/review"),
            &sam_reviewing,
            &json!({"decision": "approve"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::FORBIDDEN);
    let res = app
        .post(
            &format!("/v1/calibrations/{b}/review"),
            &rita,
            &json!({"decision": "approve", "comment": "Re-measured on STAND-2: within 1 ppm."}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let coefficients = app.get_json("/v1/sensors/TR-B/coefficients", &reader).await;
    assert_eq!(coefficients["usable"], true, "{coefficients}");

    // Without a last known good date the window starts at the standard's
    // calibration (01-17): TR-A's first calibration too, and TR-B's again.
    let mut later = nc.clone();
    later.as_object_mut().unwrap().remove("last_known_good_at");
    let res = app
        .post("/v1/standards/STAND-1/nonconformity", ADMIN, &later)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let second: Value = res.json().await.unwrap();
    assert_eq!(
        second["nonconformity"]["window_from"],
        "2026-01-17T00:00:00.000000Z"
    );
    assert_eq!(
        listed(&second),
        [
            row("TR-A", "under_review", "under_review"),
            row("TR-B", "under_review", "under_review"),
            row("TR-D", "unchanged", "withdrawn")
        ]
    );
    assert_eq!(second["calibrations"][0]["calibration_id"], a1.as_str());
    // TR-A's latest (05-01) is outside the window: still usable.
    let a = app.get_json("/v1/sensors/TR-A/coefficients", &reader).await;
    assert_eq!(a["usable"], true, "{a}");

    // Withdrawn since: the first nonconformity's list says what became of
    // each.
    let res = app
        .post(
            &format!("/v1/calibrations/{a1}/withdraw"),
            &rita,
            &json!({"reason": "spoiled by STAND-1"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let affected = app
        .get_json("/v1/standards/STAND-1/affected", &reader)
        .await;
    let ncs = affected["nonconformities"].as_array().unwrap();
    assert_eq!(ncs.len(), 2);
    assert_eq!(
        listed(&ncs[0]),
        [
            row("TR-B", "under_review", "under_review"),
            row("TR-D", "unchanged", "withdrawn")
        ],
        "the first one's TR-B was approved, then held again by the second"
    );
    assert_eq!(
        listed(&ncs[1]),
        [
            row("TR-A", "withdrawn", "withdrawn"),
            row("TR-B", "under_review", "under_review"),
            row("TR-D", "unchanged", "withdrawn")
        ]
    );

    // All of it in the audit trail.
    let actions = app.trail_actions("standards/STAND-1").await;
    assert_eq!(
        actions,
        [
            "standard.put",
            "standard.nonconformity",
            "standard.nonconformity"
        ]
    );
    let actions = app.trail_actions(&format!("calibrations/{b}")).await;
    assert_eq!(
        actions,
        [
            "calibration.submitted",
            "calibration.hold",
            "calibration.approve",
            "calibration.hold"
        ]
    );
}

#[rstest]
#[tokio::test]
async fn nonconformities_are_refused_with_reasons(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    app.put("/v1/standards/STAND-1", ADMIN, &stand()).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let nc = json!({"found_at": "2026-04-15T00:00:00Z", "reason": "drift"});
    problem(
        app.post("/v1/standards/STAND-1/nonconformity", &rita, &nc)
            .await,
        StatusCode::FORBIDDEN,
    )
    .await;
    problem(
        app.post("/v1/standards/NOPE/nonconformity", ADMIN, &nc)
            .await,
        StatusCode::NOT_FOUND,
    )
    .await;
    problem(
        app.get("/v1/standards/NOPE/affected", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    for (body, pointer) in [
        (
            json!({"found_at": "2999-01-01T00:00:00Z", "reason": "x"}),
            "/found_at",
        ),
        (
            json!({"found_at": "2025-01-01T00:00:00Z", "reason": "x"}),
            "/found_at",
        ),
        (
            json!({"found_at": "2026-04-15T00:00:00Z", "last_known_good_at": "2026-05-01T00:00:00Z", "reason": "x"}),
            "/last_known_good_at",
        ),
        (
            json!({"found_at": "2026-04-15T00:00:00Z", "reason": ""}),
            "/reason",
        ),
        (json!({"found_at": "2026-04-15T00:00:00Z"}), "/reason"),
        (
            json!({"found_at": "2026-04-15T00:00:00Z", "reason": "x", "colour": 1}),
            "/colour",
        ),
    ] {
        let p = problem(
            app.post("/v1/standards/STAND-1/nonconformity", ADMIN, &body)
                .await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(p["errors"][0]["pointer"], pointer, "{body}: {p}");
    }
    // Nothing was recorded.
    let affected = app.get_json("/v1/standards/STAND-1/affected", ADMIN).await;
    assert_eq!(affected["nonconformities"], json!([]));
}
