//! A standard found nonconforming (issue 42 item 1): a test performed inside
//! the nonconformity's window, whenever it is submitted, is stored held; one
//! performed after `found_at` with the unrepaired standard is refused, until
//! a new certificate is recorded; a correction that still uses the standard
//! is held in turn; only a reviewer's recorded disposition releases a hold;
//! and `/affected` says what became of each calibration.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal::domain::timestamp::Timestamp;
use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

const DAY: i64 = 86_400;

fn ago(seconds: i64) -> String {
    Timestamp::now().plus_seconds(-seconds).to_string()
}

fn stand(number: &str, calibrated: &str) -> Value {
    json!({
        "kind": "tumble_stand",
        "description": "Two-axis dividing head",
        "certificate": {"number": number, "issued_by": "NML", "calibrated_at": calibrated},
        "due_at": Timestamp::now().plus_seconds(300 * DAY).to_string(),
        "angle_std_arcsec": 2.0,
        "traceability": "NML angle chain",
    })
}

/// A test of `sensor` on stand DH-1, performed at `at`, by station ST-1.
fn test_at(sensor: &str, at: &str) -> Value {
    let mut s = submission(sensor, at, 4);
    s["station_id"] = json!("ST-1");
    s["standards"] = json!({"stand": "DH-1"});
    s
}

async fn state(app: &TestApp, id: &str) -> String {
    app.get_json(&format!("/v1/calibrations/{id}/signatures"), ADMIN)
        .await["state"]
        .as_str()
        .unwrap()
        .to_owned()
}

/// `(calibration, outcome)` of the nonconformity's list, as `/affected` says.
async fn affected(app: &TestApp) -> Vec<(String, String, Value)> {
    let a = app.get_json("/v1/standards/DH-1/affected", ADMIN).await;
    a["nonconformities"][0]["calibrations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["calibration_id"].as_str().unwrap().to_owned(),
                c["outcome"].as_str().unwrap().to_owned(),
                c["replaced_by"].clone(),
            )
        })
        .collect()
}

/// A service with the stand DH-1 on certificate CAL-1, calibrated 200
/// days ago.
async fn with_stand(engine: Engine) -> TestApp {
    let app = TestApp::spawn(engine).await;
    let res = app
        .put(
            "/v1/standards/DH-1",
            ADMIN,
            &stand("CAL-1", &ago(200 * DAY)),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    app
}

#[rstest]
#[tokio::test]
async fn a_nonconforming_standard_holds_late_tests_and_is_out_of_service(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = with_stand(engine).await;
    let station = app.held_token("station", "Sam Station", Some("ST-1")).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    // On time, 60 days ago: stored, then held when the nonconformity is
    // recorded.
    let early = app
        .submit(&station, &test_at("EARLY", &ago(60 * DAY)))
        .await;
    let early = early["id"].as_str().unwrap().to_owned();
    let nc = json!({"found_at": ago(DAY), "last_known_good_at": ago(100 * DAY),
        "reason": "Indexing error of 9″ at the 90° stop."});
    let res = app
        .post("/v1/standards/DH-1/nonconformity", ADMIN, &nc)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let recorded: Value = res.json().await.unwrap();
    let nc_id = recorded["nonconformity"]["id"].as_str().unwrap().to_owned();
    assert_eq!(state(&app, &early).await, "under_review");

    // Performed 40 days ago, inside the window, submitted now: stored held,
    // its result naming the nonconformity; not usable; listed.
    let late = app.submit(&station, &test_at("LATE", &ago(40 * DAY))).await;
    assert_eq!(late["held_by"][0]["nonconformity_id"], nc_id.as_str());
    let late = late["id"].as_str().unwrap().to_owned();
    assert_eq!(state(&app, &late).await, "under_review");
    let sigs = app
        .get_json(&format!("/v1/calibrations/{late}/signatures"), ADMIN)
        .await;
    assert_eq!(sigs["signatures"][0]["action"], "hold");
    assert!(
        sigs["signatures"][0]["comment"]
            .as_str()
            .unwrap()
            .contains(&nc_id),
        "{sigs}"
    );
    let c = app.get_json("/v1/sensors/LATE/coefficients", ADMIN).await;
    assert_eq!(c["usable"], false, "{c}");
    assert_eq!(c["reasons"][0]["reason"], "under_review");
    let listed = affected(&app).await;
    assert!(
        listed
            .iter()
            .any(|(id, outcome, _)| *id == late && outcome == "under_review"),
        "{listed:?}"
    );

    // Performed an hour ago with the unrepaired stand: refused, naming the
    // standard and the nonconformity; nothing stored.
    let res = app
        .post("/v1/calibrations", &station, &test_at("NOW", &ago(3600)))
        .await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(p["errors"][0]["pointer"], "/standards/stand", "{p}");
    let why = p["errors"][0]["detail"].as_str().unwrap();
    assert!(why.contains("DH-1") && why.contains(&nc_id), "{why}");
    assert_eq!(
        app.get("/v1/sensors/NOW", ADMIN).await.status(),
        StatusCode::NOT_FOUND
    );

    // The station re-sends its held calibration as a correction within its
    // day: the copy is held too, and /affected says the matter is open.
    let res = app
        .post(
            &format!("/v1/calibrations/{late}/supersede?reason=resent"),
            &station,
            &test_at("LATE", &ago(40 * DAY)),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let copy: Value = res.json().await.unwrap();
    let copy = copy["id"].as_str().unwrap().to_owned();
    assert_eq!(state(&app, &copy).await, "under_review");
    let c = app.get_json("/v1/sensors/LATE/coefficients", ADMIN).await;
    assert_eq!(c["usable"], false, "{c}");
    let listed = affected(&app).await;
    let (_, outcome, by) = listed.iter().find(|(id, ..)| *id == late).unwrap();
    assert_eq!(outcome, "under_review", "{listed:?}");
    assert_eq!(by["calibration_id"], copy.as_str());
    assert_eq!(by["state"], "under_review");

    // Only a disposition releases it: approving without one is refused.
    let review = format!("/v1/calibrations/{copy}/review");
    let res = app
        .post(&review, &rita, &json!({"decision": "approve"}))
        .await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(p["errors"][0]["pointer"], "/comment", "{p}");
    let res = app
        .post(
            &review,
            &rita,
            &json!({"decision": "approve", "comment": "no effect: kp within tolerance by 40×"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let c = app.get_json("/v1/sensors/LATE/coefficients", ADMIN).await;
    assert_eq!(c["usable"], true, "{c}");
    let listed = affected(&app).await;
    let (_, outcome, _) = listed.iter().find(|(id, ..)| *id == late).unwrap();
    assert_eq!(
        outcome, "superseded",
        "replaced by a released calibration: {listed:?}"
    );

    // Recalibrated since: a test performed now is accepted and not held.
    let res = app
        .put("/v1/standards/DH-1", ADMIN, &stand("CAL-2", &ago(3600)))
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let fresh = app.submit(&station, &test_at("FRESH", &ago(60))).await;
    assert!(fresh.get("held_by").is_none(), "{fresh}");
    let fresh = fresh["id"].as_str().unwrap().to_owned();
    assert_eq!(state(&app, &fresh).await, "submitted");
    // Before the window: never concerned.
    let before = app
        .submit(&station, &test_at("BEFORE", &ago(150 * DAY)))
        .await;
    let before = before["id"].as_str().unwrap().to_owned();
    assert_eq!(state(&app, &before).await, "submitted");
    // The trail holds every hold.
    let actions = app.trail_actions(&format!("calibrations/{late}")).await;
    assert_eq!(
        actions,
        [
            "calibration.submitted",
            "calibration.hold",
            "calibration.supersede"
        ]
    );
}

/// A triad performed inside the window is held as a single axis is.
#[rstest]
#[tokio::test]
async fn a_triad_inside_the_window_is_held(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let mut gravity = stand("G-1", &ago(200 * DAY));
    gravity["kind"] = json!("gravity");
    gravity.as_object_mut().unwrap().remove("angle_std_arcsec");
    gravity["gravity_m_s2"] = json!(9.80665);
    gravity["gravity_rel_std"] = json!(1e-5);
    assert_eq!(
        app.put("/v1/standards/G-1", ADMIN, &gravity).await.status(),
        StatusCode::CREATED
    );
    let nc = json!({"found_at": ago(DAY), "last_known_good_at": ago(100 * DAY),
        "reason": "Survey value superseded by a new campaign."});
    assert_eq!(
        app.post("/v1/standards/G-1/nonconformity", ADMIN, &nc)
            .await
            .status(),
        StatusCode::CREATED
    );
    let mut body: Value =
        serde_json::from_str(include_str!("../../examples/triad-recording.json")).unwrap();
    body["performed_at"] = json!(ago(30 * DAY));
    body["standards"] = json!({"gravity": "G-1"});
    let res = app.post("/v1/calibrations/triad", ADMIN, &body).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["held_by"][0]["standard_id"], "G-1");
    let id = r["id"].as_str().unwrap();
    assert_eq!(state(&app, id).await, "under_review");
    body["performed_at"] = json!(ago(600));
    let res = app.post("/v1/calibrations/triad", ADMIN, &body).await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(p["errors"][0]["pointer"], "/standards/gravity", "{p}");
}

/// Submissions inside the window sent while the nonconformity is being
/// recorded: whichever commits first, every one ends held — none slips
/// between the nonconformity's read of what it holds and its commit.
#[rstest]
#[tokio::test]
async fn no_submission_slips_past_a_nonconformity_being_recorded(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    use futures_util::future::join_all;
    let app = with_stand(engine).await;
    let nc = json!({"found_at": ago(DAY), "last_known_good_at": ago(100 * DAY),
        "reason": "Indexing error."});
    let bodies: Vec<Value> = (0..24)
        .map(|k| test_at(&format!("RACE-{k}"), &ago((10 + k) * DAY)))
        .collect();
    let submits = join_all(
        bodies
            .iter()
            .map(|b| app.post("/v1/calibrations", ADMIN, b)),
    );
    let record = app.post("/v1/standards/DH-1/nonconformity", ADMIN, &nc);
    let (answers, recorded) = tokio::join!(submits, record);
    assert_eq!(recorded.status(), StatusCode::CREATED);
    for a in answers {
        assert_eq!(a.status(), StatusCode::CREATED);
        let v: Value = a.json().await.unwrap();
        let id = v["id"].as_str().unwrap();
        assert_eq!(state(&app, id).await, "under_review", "{id}");
    }
    let listed = affected(&app).await;
    assert_eq!(listed.len(), 24, "{listed:?}");
}
