//! Review of calibrations (issue 28): every transition and every refusal,
//! what stops counting when a calibration is rejected or withdrawn, and the
//! approved-only serving of `--require-approval` — on both engines.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

/// Posts an act and expects `status`; answers the body.
async fn act(app: &TestApp, token: &str, path: &str, body: Value, status: StatusCode) -> Value {
    let res = app.post(path, token, &body).await;
    if status.is_success() {
        assert_eq!(res.status(), status);
        res.json().await.unwrap()
    } else {
        problem(res, status).await
    }
}

fn review(id: &Value) -> String {
    format!("/v1/calibrations/{}/review", id.as_str().unwrap())
}

fn withdraw(id: &Value) -> String {
    format!("/v1/calibrations/{}/withdraw", id.as_str().unwrap())
}

/// The states of a sensor's history, newest first.
async fn states(app: &TestApp, sensor: &str) -> Vec<(String, String)> {
    let h = app
        .get_json(&format!("/v1/sensors/{sensor}/calibrations"), ADMIN)
        .await;
    h["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["id"].as_str().unwrap().to_owned(),
                c["state"].as_str().unwrap().to_owned(),
            )
        })
        .collect()
}

#[rstest]
#[tokio::test]
async fn every_transition_and_every_refusal(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let station = app.held_token("station", "Sam Station", Some("ST-1")).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let sam_reviewing = app.held_token("reviewer", "Sam Station", None).await;
    let reader = app.token("reader", None).await;

    let mut older = submission("RV-1", "2026-01-01T00:00:00Z", 4);
    older["station_id"] = json!("ST-1");
    let mut newer = submission("RV-1", "2026-03-01T00:00:00Z", 4);
    newer["station_id"] = json!("ST-1");
    let a = app.submit(&station, &older).await["id"].clone();
    let b = app.submit(&station, &newer).await["id"].clone();
    let sensor = app.get_json("/v1/sensors/RV-1", &reader).await;
    assert_eq!(sensor["latest"]["id"], b);
    assert_eq!(sensor["latest"]["state"], "submitted");

    // Wrong role: reader and station tokens may not sign.
    for token in [&reader, &station] {
        act(
            &app,
            token,
            &review(&a),
            json!({"decision": "approve"}),
            StatusCode::FORBIDDEN,
        )
        .await;
        act(
            &app,
            token,
            &withdraw(&a),
            json!({"reason": "x"}),
            StatusCode::FORBIDDEN,
        )
        .await;
    }
    // Self-review: the same person on another token.
    let p = act(
        &app,
        &sam_reviewing,
        &review(&a),
        json!({"decision": "approve"}),
        StatusCode::FORBIDDEN,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("Sam Station"), "{p}");

    // Approve A; the sensor's cached summary follows (its latest is B).
    let done = act(
        &app,
        &rita,
        &review(&a),
        json!({"decision": "approve", "comment": "Residuals checked."}),
        StatusCode::OK,
    )
    .await;
    assert_eq!(done["state"], "approved");
    assert_eq!(done["signature"]["holder"], "Rita Reviewer");
    assert_eq!(done["signature"]["role"], "reviewer");
    assert_eq!(done["signature"]["seq"], 1);
    assert!(
        done["signature"]["meaning"]
            .as_str()
            .unwrap()
            .starts_with("Approved")
    );
    // Twice, or rejected afterwards: 409 naming the state.
    let p = act(
        &app,
        &rita,
        &review(&a),
        json!({"decision": "approve"}),
        StatusCode::CONFLICT,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("is approved"), "{p}");
    assert_eq!(p["type"], "urn:accelcal:problem:state-conflict");
    act(
        &app,
        &rita,
        &review(&a),
        json!({"decision": "reject", "comment": "late"}),
        StatusCode::CONFLICT,
    )
    .await;

    // Rejecting needs a reason; once rejected, B stops counting: A is the
    // sensor's latest again, its count one.
    let p = act(
        &app,
        &rita,
        &review(&b),
        json!({"decision": "reject"}),
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/comment"]);
    act(
        &app,
        &rita,
        &review(&b),
        json!({"decision": "reject", "comment": "Stand not levelled."}),
        StatusCode::OK,
    )
    .await;
    let sensor = app.get_json("/v1/sensors/RV-1", &reader).await;
    assert_eq!(sensor["latest"]["id"], a);
    assert_eq!(sensor["latest"]["state"], "approved");
    assert_eq!(sensor["calibration_count"], 1);
    assert_eq!(sensor["latest_performed_at"], "2026-01-01T00:00:00.000000Z");
    let coefficients = app.get_json("/v1/sensors/RV-1/coefficients", &reader).await;
    assert_eq!(coefficients["calibration_id"], a);
    assert_eq!(coefficients["basis"], "not_rejected");
    // A rejected calibration cannot be withdrawn (it never counted).
    act(
        &app,
        &rita,
        &withdraw(&b),
        json!({"reason": "x"}),
        StatusCode::CONFLICT,
    )
    .await;

    // A later submission is found against A, not the rejected B.
    let mut later = submission("RV-1", "2026-06-01T00:00:00Z", 4);
    later["station_id"] = json!("ST-1");
    let c = app.submit(&station, &later).await;
    assert_eq!(c["as_found"]["previous_calibration_id"], a);
    let c = c["id"].clone();

    // Withdraw C (submitted) and A (approved): a reason is needed, once.
    let p = act(
        &app,
        &rita,
        &withdraw(&c),
        json!({}),
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/reason"]);
    act(
        &app,
        ADMIN,
        &withdraw(&c),
        json!({"reason": "Wrong sensor id."}),
        StatusCode::OK,
    )
    .await;
    let w = act(
        &app,
        &rita,
        &withdraw(&a),
        json!({"reason": "Stand moved."}),
        StatusCode::OK,
    )
    .await;
    assert_eq!(w["signature"]["seq"], 2);
    act(
        &app,
        &rita,
        &withdraw(&a),
        json!({"reason": "again"}),
        StatusCode::CONFLICT,
    )
    .await;
    act(
        &app,
        &rita,
        &review(&a),
        json!({"decision": "approve"}),
        StatusCode::CONFLICT,
    )
    .await;

    // Nothing counts: the sensor is served no more, but its history stays,
    // every calibration with its state.
    problem(
        app.get("/v1/sensors/RV-1", &reader).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    problem(
        app.get("/v1/sensors/RV-1/coefficients", &reader).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    let s = |id: &Value, state: &str| (id.as_str().unwrap().to_owned(), state.to_owned());
    assert_eq!(
        states(&app, "RV-1").await,
        [s(&c, "withdrawn"), s(&b, "rejected"), s(&a, "withdrawn")]
    );
    // Compensation with a withdrawn calibration named: not usable, says why.
    let comp = act(
        &app,
        &reader,
        "/v1/sensors/RV-1/compensate",
        json!({"outputs": [0.5], "calibration_id": a}),
        StatusCode::OK,
    )
    .await;
    assert_eq!(comp["usable"], false);
    assert_eq!(comp["reasons"][0]["reason"], "withdrawn");
    assert_eq!(comp["state"], "withdrawn");

    // A's record: state and both signatures, in order.
    let record = app
        .get_json(
            &format!("/v1/calibrations/{}/signatures", a.as_str().unwrap()),
            &reader,
        )
        .await;
    assert_eq!(record["state"], "withdrawn");
    let sigs = record["signatures"].as_array().unwrap();
    let acts: Vec<(&str, &str, &str)> = sigs
        .iter()
        .map(|s| {
            (
                s["action"].as_str().unwrap(),
                s["holder"].as_str().unwrap(),
                s["comment"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        acts,
        [
            ("approve", "Rita Reviewer", "Residuals checked."),
            ("withdraw", "Rita Reviewer", "Stand moved.")
        ]
    );
    // The admin token signs as itself, without a holder.
    let c_record = app
        .get_json(
            &format!("/v1/calibrations/{}/signatures", c.as_str().unwrap()),
            &reader,
        )
        .await;
    assert_eq!(c_record["signatures"][0]["token_id"], "env-admin");
    assert_eq!(c_record["signatures"][0]["holder"], Value::Null);
    assert_eq!(c_record["signatures"][0]["role"], "admin");

    // A new submission brings the sensor back, found against nothing.
    let d = app
        .submit(&station, &submission("RV-1", "2026-09-01T00:00:00Z", 4))
        .await;
    assert_eq!(d["as_found"], Value::Null);
    let sensor = app.get_json("/v1/sensors/RV-1", &reader).await;
    assert_eq!(
        (
            sensor["calibration_count"].clone(),
            sensor["latest"]["id"].clone()
        ),
        (json!(1), d["id"].clone())
    );

    // A reviewer who submitted may not approve their own work, but may
    // withdraw it; without holders the token is the person.
    let anonymous = app.token("reviewer", None).await;
    let e = app
        .submit(&anonymous, &submission("RV-2", "2026-01-01T00:00:00Z", 4))
        .await["id"]
        .clone();
    act(
        &app,
        &anonymous,
        &review(&e),
        json!({"decision": "approve"}),
        StatusCode::FORBIDDEN,
    )
    .await;
    act(
        &app,
        &anonymous,
        &withdraw(&e),
        json!({"reason": "Mine, wrong."}),
        StatusCode::OK,
    )
    .await;

    // Unknown and malformed ids.
    let unknown = "/v1/calibrations/01900000-0000-7000-8000-000000000000";
    problem(
        app.post(
            &format!("{unknown}/review"),
            &rita,
            &json!({"decision": "approve"}),
        )
        .await,
        StatusCode::NOT_FOUND,
    )
    .await;
    problem(
        app.get(&format!("{unknown}/signatures"), &reader).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    let p = act(
        &app,
        &rita,
        &review(&a),
        json!({"decision": "maybe"}),
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/decision"]);
}

#[rstest]
#[tokio::test]
async fn require_approval_serves_approved_calibrations_only(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::configured(engine, |c| {
        c.web.basis = accelcal::domain::review::Basis::ApprovedOnly;
    })
    .await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let approve = |id: Value| {
        let app = &app;
        let rita = rita.clone();
        async move {
            act(
                app,
                &rita,
                &review(&id),
                json!({"decision": "approve"}),
                StatusCode::OK,
            )
            .await;
        }
    };
    let a = app
        .submit(ADMIN, &submission("RA-1", "2026-01-01T00:00:00Z", 4))
        .await;
    assert_eq!(a["as_found"], Value::Null);
    let a = a["id"].clone();

    // Nothing approved: the sensor is listed, but serves no coefficients.
    let sensor = app.get_json("/v1/sensors/RA-1", ADMIN).await;
    assert_eq!(sensor["latest"]["id"], a);
    let p = problem(
        app.get("/v1/sensors/RA-1/coefficients", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("no approved calibration"),
        "{p}"
    );
    problem(
        app.post(
            "/v1/sensors/RA-1/compensate",
            ADMIN,
            &json!({"outputs": [0.5]}),
        )
        .await,
        StatusCode::NOT_FOUND,
    )
    .await;

    approve(a.clone()).await;
    let coefficients = app.get_json("/v1/sensors/RA-1/coefficients", ADMIN).await;
    assert_eq!(coefficients["calibration_id"], a);
    assert_eq!(coefficients["basis"], "approved_only");

    // B is newer but not approved: A still serves, and C is found against A.
    let b = app
        .submit(ADMIN, &submission("RA-1", "2026-03-01T00:00:00Z", 4))
        .await["id"]
        .clone();
    assert_eq!(
        app.get_json("/v1/sensors/RA-1", ADMIN).await["latest"]["id"],
        b
    );
    assert_eq!(
        app.get_json("/v1/sensors/RA-1/coefficients", ADMIN).await["calibration_id"],
        a
    );
    let comp = act(
        &app,
        ADMIN,
        "/v1/sensors/RA-1/compensate",
        json!({"outputs": [0.5]}),
        StatusCode::OK,
    )
    .await;
    assert_eq!(
        (comp["calibration_id"].clone(), comp["usable"].clone()),
        (a.clone(), json!(true))
    );
    // Named, B is not usable: not approved.
    let comp = act(
        &app,
        ADMIN,
        "/v1/sensors/RA-1/compensate",
        json!({"outputs": [0.5], "calibration_id": b}),
        StatusCode::OK,
    )
    .await;
    assert_eq!(comp["reasons"][0]["reason"], "not_approved");
    let c = app
        .submit(ADMIN, &submission("RA-1", "2026-05-01T00:00:00Z", 4))
        .await;
    assert_eq!(c["as_found"]["previous_calibration_id"], a);
    let stability = app.get_json("/v1/sensors/RA-1/stability", ADMIN).await;
    assert_eq!(stability["calibrations"], 1);
    assert_eq!(stability["basis"], "approved_only", "{stability}");

    // Approving B makes it the served one, and a stability point.
    approve(b.clone()).await;
    assert_eq!(
        app.get_json("/v1/sensors/RA-1/coefficients", ADMIN).await["calibration_id"],
        b
    );
    assert_eq!(
        app.get_json("/v1/sensors/RA-1/stability", ADMIN).await["calibrations"],
        2
    );
    // Withdrawing it falls back to A.
    act(
        &app,
        &rita,
        &withdraw(&b),
        json!({"reason": "Drifted stand."}),
        StatusCode::OK,
    )
    .await;
    assert_eq!(
        app.get_json("/v1/sensors/RA-1/coefficients", ADMIN).await["calibration_id"],
        a
    );
    assert_eq!(
        app.get_json("/v1/sensors/RA-1/stability", ADMIN).await["calibrations"],
        1
    );
}

#[rstest]
#[tokio::test]
async fn a_corrected_submission_supersedes_once(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let station = app.held_token("station", "Sam Station", Some("ST-1")).await;
    let other_station = app.held_token("station", "Olga Other", Some("ST-2")).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let mut wrong = submission("WRONG-1", "2026-01-01T00:00:00Z", 4);
    wrong["station_id"] = json!("ST-1");
    let a = app.submit(&station, &wrong).await["id"].clone();
    let supersede = |id: &Value, reason: &str| {
        format!(
            "/v1/calibrations/{}/supersede?reason={}",
            id.as_str().unwrap(),
            reason.replace(' ', "%20")
        )
    };
    let mut right = wrong.clone();
    right["sensor_id"] = json!("RIGHT-1");

    // No reason, another station, an unknown calibration: refused, nothing
    // stored.
    let p = problem(
        app.post(
            &format!("/v1/calibrations/{}/supersede", a.as_str().unwrap()),
            &station,
            &right,
        )
        .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "reason", "{p}");
    problem(
        app.post(&supersede(&a, "wrong sensor"), &other_station, &right)
            .await,
        StatusCode::FORBIDDEN,
    )
    .await;
    problem(
        app.post(
            "/v1/calibrations/01900000-0000-7000-8000-000000000000/supersede?reason=x",
            &rita,
            &right,
        )
        .await,
        StatusCode::NOT_FOUND,
    )
    .await;
    problem(
        app.get("/v1/sensors/RIGHT-1", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;

    // The station that submitted it corrects the sensor id itself.
    let res = app
        .post(&supersede(&a, "wrong sensor id"), &station, &right)
        .await;
    let status = res.status();
    let location = res.headers().get("location").cloned();
    let text = res.text().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{text}");
    let b: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(
        location.unwrap().to_str().unwrap(),
        format!("/v1/calibrations/{}", b["id"].as_str().unwrap())
    );
    assert_eq!(
        b["supersedes"],
        json!({"calibration_id": a, "reason": "wrong sensor id"})
    );
    assert_eq!(b["sensor_id"], "RIGHT-1");
    assert_eq!(
        app.get_json("/v1/sensors/RIGHT-1", ADMIN).await["latest"]["id"],
        b["id"]
    );
    problem(
        app.get("/v1/sensors/WRONG-1", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    let record = app
        .get_json(
            &format!("/v1/calibrations/{}/signatures", a.as_str().unwrap()),
            ADMIN,
        )
        .await;
    assert_eq!(record["state"], "superseded");
    assert_eq!(record["signatures"][0]["superseded_by"], b["id"]);
    assert_eq!(record["signatures"][0]["holder"], "Sam Station");
    assert_eq!(record["signatures"][0]["role"], "station");

    // Superseding twice is a 409, and stores nothing.
    let p = problem(
        app.post(&supersede(&a, "again"), &rita, &right).await,
        StatusCode::CONFLICT,
    )
    .await;
    assert!(
        p["detail"].as_str().unwrap().contains("is superseded"),
        "{p}"
    );
    let history = app
        .get_json("/v1/sensors/RIGHT-1/calibrations", ADMIN)
        .await;
    assert_eq!(history["items"].as_array().unwrap().len(), 1);

    // A reviewer supersedes an approved calibration; the old certificate
    // says so on every page, the new one names what it replaces.
    let b = b["id"].clone();
    act(
        &app,
        &rita,
        &review(&b),
        json!({"decision": "approve"}),
        StatusCode::OK,
    )
    .await;
    let mut corrected = right.clone();
    corrected["performed_at"] = json!("2026-01-02T00:00:00Z");
    let res = app
        .post(&supersede(&b, "performed a day later"), &rita, &corrected)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let c: Value = res.json().await.unwrap();
    let sensor = app.get_json("/v1/sensors/RIGHT-1", ADMIN).await;
    assert_eq!(
        (
            sensor["latest"]["id"].clone(),
            sensor["calibration_count"].clone()
        ),
        (c["id"].clone(), json!(1))
    );
    let old = app
        .get(
            &format!("/v1/calibrations/{}/certificate", b.as_str().unwrap()),
            ADMIN,
        )
        .await
        .text()
        .await
        .unwrap();
    let header = &old[old.find("<thead>").unwrap()..old.find("</thead>").unwrap()];
    assert!(
        header.contains("SUPERSEDED") && header.contains(c["id"].as_str().unwrap()),
        "{header}"
    );
    let new = app
        .get(
            &format!("/v1/calibrations/{}/certificate", c["id"].as_str().unwrap()),
            ADMIN,
        )
        .await
        .text()
        .await
        .unwrap();
    assert!(
        new.contains(&format!(
            "replaces certificate No. <code>{}</code>",
            b.as_str().unwrap()
        )),
        "the replaced certificate"
    );
    // Neither withdrawn nor approved afterwards.
    act(
        &app,
        &rita,
        &withdraw(&b),
        json!({"reason": "x"}),
        StatusCode::CONFLICT,
    )
    .await;
}

#[rstest]
#[tokio::test]
async fn reprocessing_confirms_or_supersedes(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let station = app.token("station", None).await;
    let reprocess = |id: &Value| format!("/v1/calibrations/{}/reprocess", id.as_str().unwrap());

    // The same method gives the same numbers: confirmed, state kept.
    let a = app.submit(ADMIN, &paper()).await["id"].clone();
    problem(
        app.post(&reprocess(&a), &station, &json!({})).await,
        StatusCode::FORBIDDEN,
    )
    .await;
    let r = act(&app, &rita, &reprocess(&a), json!({}), StatusCode::OK).await;
    assert_eq!(r["outcome"], "confirmed");
    assert_eq!(r["changed"], json!([]));
    assert_eq!(r["replacement_id"], Value::Null);
    assert_eq!(r["signature"]["action"], "confirm");
    assert_eq!(r["signature"]["state"], "submitted");
    act(
        &app,
        &rita,
        &review(&a),
        json!({"decision": "approve"}),
        StatusCode::OK,
    )
    .await;
    let r = act(&app, &rita, &reprocess(&a), json!({}), StatusCode::OK).await;
    assert_eq!(
        (r["outcome"].clone(), r["signature"]["state"].clone()),
        (json!("confirmed"), json!("approved"))
    );
    let record = app
        .get_json(
            &format!("/v1/calibrations/{}/signatures", a.as_str().unwrap()),
            ADMIN,
        )
        .await;
    assert_eq!(record["state"], "approved");
    assert_eq!(record["signatures"].as_array().unwrap().len(), 3);

    // A calibration stored by an older method (its ki off by 1e-9): the
    // submission computed again supersedes it with today's numbers — those
    // /v1/identify gives for the same body.
    let mut body = paper();
    body["sensor_id"] = json!("OLD-METHOD");
    let truth = act(&app, ADMIN, "/v1/identify", body.clone(), StatusCode::OK).await;
    let old_id = crate::older::store_by_an_older_method(&app, &body, &truth, "env-admin").await;
    let old = json!(old_id.to_string());
    let r = act(&app, &rita, &reprocess(&old), json!({}), StatusCode::OK).await;
    assert_eq!(r["outcome"], "superseded");
    assert_eq!(r["changed"], json!(["ki coefficient"]));
    let new = r["replacement_id"].clone();
    let result = app
        .get_json(
            &format!("/v1/calibrations/{}", new.as_str().unwrap()),
            ADMIN,
        )
        .await;
    assert_eq!(
        result["fused"], truth["fused"],
        "today's numbers, bit for bit"
    );
    assert_eq!(
        result["received_at"], "2026-11-01T00:00:00.000000Z",
        "as it was received"
    );
    assert_eq!(result["supersedes"]["calibration_id"], old);
    assert!(
        result["supersedes"]["reason"]
            .as_str()
            .unwrap()
            .starts_with("reprocessed with accelcal ")
    );
    let sig = &r["signature"];
    assert_eq!(sig["superseded_by"], new);
    assert!(
        sig["comment"]
            .as_str()
            .unwrap()
            .ends_with(": ki coefficient changed"),
        "{sig}"
    );
    assert_eq!(
        app.get_json("/v1/sensors/OLD-METHOD", ADMIN).await["latest"]["id"],
        new
    );
    // Superseded now: no second reprocessing.
    act(
        &app,
        &rita,
        &reprocess(&old),
        json!({}),
        StatusCode::CONFLICT,
    )
    .await;
}
