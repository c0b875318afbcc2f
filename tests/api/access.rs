//! The access matrix: every endpoint (21) × {no token, malformed, revoked, reader,
//! station, other station, reviewer, admin} → the expected status.

use reqwest::{Method, StatusCode};
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Who {
    NoToken,
    Malformed,
    Revoked,
    Reader,
    /// A station token bound to ST-A (the station the submission names).
    Station,
    /// A station token bound to ST-B.
    OtherStation,
    /// A reviewer (above a station, bound to none), with a holder.
    Reviewer,
    Admin,
}

const EVERYONE: [Who; 8] = [
    Who::NoToken,
    Who::Malformed,
    Who::Revoked,
    Who::Reader,
    Who::Station,
    Who::OtherStation,
    Who::Reviewer,
    Who::Admin,
];

/// The least rights an operation needs.
#[derive(Clone, Copy)]
enum Needs {
    Read,
    /// Submit as station ST-A.
    SubmitAsA,
    Admin,
}

fn expected(who: Who, needs: Needs, ok: StatusCode) -> StatusCode {
    use Who::*;
    match (who, needs) {
        (NoToken | Malformed | Revoked, _) => StatusCode::UNAUTHORIZED,
        (_, Needs::Read) => ok,
        (Station | Reviewer | Admin, Needs::SubmitAsA) => ok,
        (Reader | OtherStation, Needs::SubmitAsA) => StatusCode::FORBIDDEN,
        (Admin, Needs::Admin) => ok,
        (_, Needs::Admin) => StatusCode::FORBIDDEN,
    }
}

#[rstest]
#[tokio::test]
async fn every_endpoint_against_every_kind_of_caller(#[values(Sqlite, Postgres)] engine: Engine) {
    // Every kind of bad credential, many times over, from one address: the
    // throttle of failed authentications (tested in `round_three`) is
    // widened so that each answer here is the one the credential earns.
    let app = TestApp::configured(engine, |c| c.limits.auth_failure_burst = 10_000).await;
    let revoked: Value = app
        .post("/v1/tokens", ADMIN, &json!({"role": "admin"}))
        .await
        .json()
        .await
        .unwrap();
    let del = app.url(&format!("/v1/tokens/{}", revoked["id"].as_str().unwrap()));
    assert_eq!(
        app.client
            .delete(del)
            .bearer_auth(ADMIN)
            .send()
            .await
            .unwrap()
            .status(),
        StatusCode::NO_CONTENT
    );
    let reviewer: Value = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "reviewer", "holder": "Ana Ruiz"}),
        )
        .await
        .json()
        .await
        .unwrap();
    let reviewer = reviewer["token"].as_str().unwrap().to_owned();
    let tokens = [
        (Who::NoToken, None),
        (
            Who::Malformed,
            Some("acc_0123456789abcdef0123456789abcdef_not-a-real-secret".to_owned()),
        ),
        (
            Who::Revoked,
            Some(revoked["token"].as_str().unwrap().to_owned()),
        ),
        (Who::Reader, Some(app.token("reader", None).await)),
        (Who::Station, Some(app.token("station", Some("ST-A")).await)),
        (
            Who::OtherStation,
            Some(app.token("station", Some("ST-B")).await),
        ),
        (Who::Reviewer, Some(reviewer)),
        (Who::Admin, Some(app.token("admin", None).await)),
    ];
    let r = app
        .submit(ADMIN, &submission("M-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let id = r["id"].as_str().unwrap();
    let nav =
        json!({"unit": "mA", "limits": {"k0": {"min": -1, "max": 1}}, "decision_rule": "simple"});
    let created = app
        .client
        .put(app.url("/v1/sensor-types/NAV"))
        .bearer_auth(ADMIN)
        .json(&nav)
        .send()
        .await
        .unwrap();
    assert_eq!(created.status(), StatusCode::CREATED);
    let stand: Value =
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap();
    let created = app.put("/v1/standards/STAND-1", ADMIN, &stand).await;
    assert_eq!(created.status(), StatusCode::CREATED);
    let mut as_a = submission("M-2", "2026-01-01T00:00:00Z", 4);
    as_a["station_id"] = json!("ST-A");

    let ops: Vec<(Method, String, Option<Value>, Needs, StatusCode)> = vec![
        (
            Method::POST,
            "/v1/calibrations".into(),
            Some(as_a),
            Needs::SubmitAsA,
            StatusCode::CREATED,
        ),
        (
            Method::GET,
            format!("/v1/calibrations/{id}"),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            format!("/v1/calibrations/{id}/submission"),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            format!("/v1/calibrations/{id}/certificate"),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensors".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensors?search=m-&status=unknown".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensors/M-1".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensors/M-1/calibrations".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensors/M-1/coefficients".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::POST,
            "/v1/sensors/M-1/compensate".into(),
            Some(json!({"outputs": [0.5]})),
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensors/M-1/stability".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::PUT,
            "/v1/sensors/M-1".into(),
            Some(json!({"sensor_type": "NAV"})),
            Needs::Admin,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensor-types".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/sensor-types/NAV".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::PUT,
            "/v1/sensor-types/NAV".into(),
            Some(nav.clone()),
            Needs::Admin,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/standards".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::GET,
            "/v1/standards/STAND-1".into(),
            None,
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::PUT,
            "/v1/standards/STAND-1".into(),
            Some(stand.clone()),
            Needs::Admin,
            StatusCode::OK,
        ),
        (
            Method::POST,
            "/v1/identify".into(),
            Some(paper()),
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::POST,
            "/v1/fuse".into(),
            Some(json!({"values": {"k0": [1, 2, 4, 7]}})),
            Needs::Read,
            StatusCode::OK,
        ),
        (
            Method::POST,
            "/v1/tokens".into(),
            Some(json!({"role": "reader"})),
            Needs::Admin,
            StatusCode::CREATED,
        ),
        (
            Method::GET,
            "/v1/tokens".into(),
            None,
            Needs::Admin,
            StatusCode::OK,
        ),
        (
            Method::DELETE,
            "/v1/tokens/{victim}".into(),
            None,
            Needs::Admin,
            StatusCode::NO_CONTENT,
        ),
    ];
    let mut checked = 0;
    for (method, path, body, needs, ok) in &ops {
        for (who, token) in &tokens {
            let path = if path.contains("{victim}") {
                let victim: Value = app
                    .post("/v1/tokens", ADMIN, &json!({"role": "reader"}))
                    .await
                    .json()
                    .await
                    .unwrap();
                path.replace("{victim}", victim["id"].as_str().unwrap())
            } else {
                path.clone()
            };
            let mut req = app.client.request(method.clone(), app.url(&path));
            if let Some(t) = token {
                req = req.bearer_auth(t);
            }
            if let Some(b) = body {
                req = req.json(b);
            }
            let res = req.send().await.unwrap();
            let want = expected(*who, *needs, *ok);
            assert_eq!(res.status(), want, "{who:?} {method} {path}");
            if !want.is_success() {
                problem(res, want).await;
            }
            checked += 1;
        }
    }
    assert_eq!(checked, ops.len() * EVERYONE.len());
    // The station's submissions carry its station.
    let history: Value = app
        .get("/v1/sensors/M-2/calibrations", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert!(
        history["items"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| c["station_id"] == "ST-A")
    );
}
