//! Every endpoint's happy path: sensors, history, pagination, coefficients,
//! compensation, identify, tokens, probes and station binding.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

async fn page_through(app: &TestApp, first: &str) -> Vec<Vec<String>> {
    let mut pages = Vec::new();
    let mut url = first.to_owned();
    loop {
        let res = app.get(&url, ADMIN).await;
        assert_eq!(res.status(), StatusCode::OK);
        let page: Value = res.json().await.unwrap();
        let ids = page["items"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| {
                i.get("id")
                    .or(i.get("sensor_id"))
                    .unwrap()
                    .as_str()
                    .unwrap()
                    .to_owned()
            })
            .collect();
        pages.push(ids);
        match page["next"].as_str() {
            Some(next) => {
                let sep = if first.contains('?') { '&' } else { '?' };
                url = format!("{}{sep}after={next}", first);
            }
            None => break,
        }
    }
    pages
}

/// The coefficients answer (rendered once per calibration) always names
/// the sensor's latest calibration: a newer one replaces it at once, an
/// older one does not.
#[rstest]
#[tokio::test]
async fn coefficients_follow_the_latest_calibration(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let get = || async {
        let res = app.get("/v1/sensors/S-C/coefficients", ADMIN).await;
        assert_eq!(res.status(), StatusCode::OK);
        assert_eq!(res.headers()["content-type"], "application/json");
        res.bytes().await.unwrap()
    };
    let check = |body: &[u8], calibration: &Value| {
        let v: Value = serde_json::from_slice(body).unwrap();
        assert_eq!(v["sensor_id"], "S-C");
        assert_eq!(v["calibration_id"], calibration["id"]);
        assert_eq!(v["performed_at"], calibration["performed_at"]);
        assert_eq!(v["unit"], "mA");
        assert_eq!(v["model"], calibration["model"]);
        assert_eq!(v["coefficients"], calibration["fused"]["coefficients"]);
        assert_eq!(v["std_errors"], calibration["fused"]["std_errors"]);
    };
    let first = app
        .submit(ADMIN, &submission("S-C", "2026-01-01T00:00:00Z", 4))
        .await;
    let a = get().await;
    check(&a, &first);
    assert_eq!(get().await, a, "a second read answers the same bytes");

    let newer = app
        .submit(ADMIN, &submission("S-C", "2026-06-01T00:00:00Z", 6))
        .await;
    assert_ne!(
        newer["fused"]["coefficients"],
        first["fused"]["coefficients"]
    );
    check(&get().await, &newer);

    app.submit(ADMIN, &submission("S-C", "2025-01-01T00:00:00Z", 5))
        .await;
    check(&get().await, &newer);
}

#[rstest]
#[tokio::test]
async fn sensors_are_listed_in_pages_with_their_latest_calibration(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    for s in ["S-5", "S-1", "S-3", "S-2", "S-4"] {
        app.submit(ADMIN, &submission(s, "2026-01-01T00:00:00Z", 4))
            .await;
    }
    // S-3 gets an older and a newer calibration; the newer is "latest".
    let newer = app
        .submit(ADMIN, &submission("S-3", "2026-06-01T00:00:00Z", 4))
        .await;
    app.submit(ADMIN, &submission("S-3", "2025-06-01T00:00:00Z", 4))
        .await;

    let pages = page_through(&app, "/v1/sensors?limit=2").await;
    assert_eq!(pages, [vec!["S-1", "S-2"], vec!["S-3", "S-4"], vec!["S-5"]]);

    let s3: Value = app
        .get("/v1/sensors/S-3", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(s3["calibration_count"], 3);
    assert_eq!(s3["latest"]["id"], newer["id"]);
    assert_eq!(s3["first_performed_at"], "2025-06-01T00:00:00.000000Z");
    assert_eq!(s3["latest_performed_at"], "2026-06-01T00:00:00.000000Z");
    assert_eq!(s3["latest"]["coefficients"], newer["fused"]["coefficients"]);
    assert_eq!(s3["latest"]["runs"], 4);

    let missing = app.get("/v1/sensors/NOPE", ADMIN).await;
    problem(missing, StatusCode::NOT_FOUND).await;
}

#[rstest]
#[tokio::test]
async fn history_is_newest_first_filtered_and_paginated(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let mut ids = Vec::new();
    let mut answers = Vec::new();
    for month in [3, 1, 5, 2, 4] {
        let r = app
            .submit(
                ADMIN,
                &submission("H-1", &format!("2026-0{month}-01T00:00:00Z"), 4),
            )
            .await;
        ids.push((month, r["id"].as_str().unwrap().to_owned()));
        answers.push(r);
    }
    ids.sort();
    let newest_first: Vec<String> = ids.iter().rev().map(|(_, id)| id.clone()).collect();

    let pages = page_through(&app, "/v1/sensors/H-1/calibrations?limit=2").await;
    assert_eq!(pages.concat(), newest_first);
    assert_eq!(pages.len(), 3);

    let pages = page_through(
        &app,
        "/v1/sensors/H-1/calibrations?from=2026-02-01T00:00:00Z&to=2026-04-01T00:00:00%2B00:00",
    )
    .await;
    assert_eq!(pages.concat(), newest_first[1..4]);

    // Read again — every summary now kept rendered — each item is still
    // its submission's answer, and a newer calibration heads the next read.
    let read = || async {
        let res = app
            .get("/v1/sensors/H-1/calibrations?limit=10", ADMIN)
            .await;
        assert_eq!(res.status(), StatusCode::OK);
        assert_eq!(res.headers()["content-type"], "application/json");
        res.bytes().await.unwrap()
    };
    let warm = read().await;
    assert_eq!(read().await, warm, "a second read answers the same bytes");
    let page: Value = serde_json::from_slice(&warm).unwrap();
    assert_eq!(page["next"], Value::Null);
    let items = page["items"].as_array().unwrap();
    assert_eq!(items.len(), 5);
    for item in items {
        let answer = answers.iter().find(|a| a["id"] == item["id"]).unwrap();
        assert_eq!(item["performed_at"], answer["performed_at"]);
        assert_eq!(item["coefficients"], answer["fused"]["coefficients"]);
        assert_eq!(item["std_errors"], answer["fused"]["std_errors"]);
        assert_eq!(item["model"], answer["model"]);
        assert_eq!(item["runs"], 4);
        assert_eq!(item["sensor_id"], "H-1");
    }
    let newer = app
        .submit(ADMIN, &submission("H-1", "2026-07-01T00:00:00Z", 4))
        .await;
    let page: Value = serde_json::from_slice(&read().await).unwrap();
    let items = page["items"].as_array().unwrap();
    assert_eq!(items.len(), 6);
    assert_eq!(items[0]["id"], newer["id"]);
    assert_eq!(items[1..], page_items(&warm)[..]);

    let res = app.get("/v1/sensors/NOPE/calibrations", ADMIN).await;
    problem(res, StatusCode::NOT_FOUND).await;
}

#[rstest]
#[tokio::test]
async fn compensation_inverts_the_stored_model(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let first = app
        .submit(ADMIN, &submission("C-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let latest = app
        .submit(ADMIN, &submission("C-1", "2026-02-01T00:00:00Z", 6))
        .await;
    let k = &latest["fused"]["coefficients"];
    let (k0, ki, kp) = (
        k["k0"].as_f64().unwrap(),
        k["ki"].as_f64().unwrap(),
        k["kp"].as_f64().unwrap(),
    );
    let inputs = [-1.0, -0.25, 0.0, 0.5, 1.0];
    let a_p = [0.0, 0.5, -0.3, 0.0, 0.1];
    let outputs: Vec<f64> = inputs
        .iter()
        .zip(a_p)
        .map(|(a, p)| k0 + ki * a + kp * p)
        .collect();

    let res = app
        .post(
            "/v1/sensors/C-1/compensate",
            ADMIN,
            &json!({"outputs": outputs, "a_p": a_p}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["calibration_id"], latest["id"]);
    assert_eq!(r["unit"], "mA");
    let a_i = r["a_i"].as_array().unwrap();
    assert_eq!(a_i.len(), inputs.len(), "one input per output: {a_i:?}");
    for (got, want) in a_i.iter().zip(inputs) {
        close(got, want, 1e-12);
    }

    // A named (older) calibration gives slightly different inputs.
    let res = app
        .post(
            "/v1/sensors/C-1/compensate",
            ADMIN,
            &json!({"outputs": outputs, "a_p": a_p, "calibration_id": first["id"]}),
        )
        .await;
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["calibration_id"], first["id"]);

    // A calibration of another sensor is not this sensor's.
    let other = app
        .submit(ADMIN, &submission("C-2", "2026-01-01T00:00:00Z", 4))
        .await;
    let res = app
        .post(
            "/v1/sensors/C-1/compensate",
            ADMIN,
            &json!({"outputs": [0.1], "calibration_id": other["id"]}),
        )
        .await;
    problem(res, StatusCode::NOT_FOUND).await;
    let res = app
        .post(
            "/v1/sensors/NOPE/compensate",
            ADMIN,
            &json!({"outputs": [0.1]}),
        )
        .await;
    problem(res, StatusCode::NOT_FOUND).await;
    let res = app
        .post(
            "/v1/sensors/C-1/compensate",
            ADMIN,
            &json!({"outputs": [0.1, 0.2], "a_p": [0.0]}),
        )
        .await;
    assert_eq!(
        pointers(&problem(res, StatusCode::UNPROCESSABLE_ENTITY).await),
        ["/a_p"]
    );
}

#[rstest]
#[tokio::test]
async fn identify_computes_without_storing(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let res = app.post("/v1/identify", ADMIN, &paper()).await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    assert!(r.get("id").is_none());
    close(&r["fused"]["coefficients"]["kp"], 0.0062738448, 1e-9);
    let sensors: Value = app.get("/v1/sensors", ADMIN).await.json().await.unwrap();
    assert_eq!(sensors["items"], json!([]));
}

#[rstest]
#[tokio::test]
async fn tokens_are_created_listed_without_secrets_and_revoked(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let res = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "reader", "label": "dashboard"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let created: Value = res.json().await.unwrap();
    let token = created["token"].as_str().unwrap().to_owned();
    assert!(token.starts_with("acc_"));
    assert_eq!(
        app.get("/v1/sensors", &token).await.status(),
        StatusCode::OK
    );

    let list = app.get("/v1/tokens", ADMIN).await.text().await.unwrap();
    assert!(
        !list.contains(&token[token.len() - 43..]),
        "secret listed: {list}"
    );
    let list: Value = serde_json::from_str(&list).unwrap();
    let item = &list["items"][0];
    assert_eq!(item["id"], created["id"]);
    assert_eq!(item["label"], "dashboard");
    assert_eq!(item["revoked_at"], Value::Null);
    assert!(item.get("token").is_none() && item.get("secret_hash").is_none());

    let path = format!("/v1/tokens/{}", created["id"].as_str().unwrap());
    let res = app
        .client
        .delete(app.url(&path))
        .bearer_auth(ADMIN)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::NO_CONTENT);
    let res = app.get("/v1/sensors", &token).await;
    assert!(
        problem(res, StatusCode::UNAUTHORIZED).await["detail"]
            .as_str()
            .unwrap()
            .contains("revoked")
    );
    let res = app
        .client
        .delete(app.url(&path))
        .bearer_auth(ADMIN)
        .send()
        .await
        .unwrap();
    problem(res, StatusCode::NOT_FOUND).await;

    let res = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "reader", "station_id": "ST-1"}),
        )
        .await;
    assert_eq!(
        pointers(&problem(res, StatusCode::UNPROCESSABLE_ENTITY).await),
        ["/station_id"]
    );

    // A reviewer named by its holder: shown when created and listed, kept
    // across the store; a holder on two lines is refused, naming it.
    let res = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "reviewer", "holder": "Ana Ruiz-Pérez", "label": "QA"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let reviewer: Value = res.json().await.unwrap();
    assert_eq!(
        (&reviewer["role"], &reviewer["holder"]),
        (&json!("reviewer"), &json!("Ana Ruiz-Pérez"))
    );
    let list: Value = app.get("/v1/tokens", ADMIN).await.json().await.unwrap();
    let listed = list["items"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["id"] == reviewer["id"])
        .expect("the reviewer is listed");
    assert_eq!(listed["holder"], "Ana Ruiz-Pérez");
    assert_eq!(listed["role"], "reviewer");
    assert_eq!(list["items"][0]["holder"], Value::Null);
    let as_reviewer = reviewer["token"].as_str().unwrap();
    assert_eq!(
        app.get("/v1/tokens", as_reviewer).await.status(),
        StatusCode::FORBIDDEN
    );
    let res = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "reviewer", "holder": "Ana\nRuiz"}),
        )
        .await;
    assert_eq!(
        pointers(&problem(res, StatusCode::UNPROCESSABLE_ENTITY).await),
        ["/holder"]
    );
}

#[rstest]
#[tokio::test]
async fn station_tokens_record_and_guard_their_station(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let st1 = app.token("station", Some("ST-1")).await;
    let r = app
        .submit(&st1, &submission("B-1", "2026-01-01T00:00:00Z", 4))
        .await;
    assert_eq!(r["station_id"], "ST-1");
    let mut claimed = submission("B-1", "2026-01-02T00:00:00Z", 4);
    claimed["station_id"] = json!("ST-1");
    app.submit(&st1, &claimed).await;
    claimed["station_id"] = json!("ST-2");
    let res = app.post("/v1/calibrations", &st1, &claimed).await;
    problem(res, StatusCode::FORBIDDEN).await;
    // An unbound station token records what the body says.
    let free = app.token("station", None).await;
    assert_eq!(app.submit(&free, &claimed).await["station_id"], "ST-2");
}

#[rstest]
#[tokio::test]
async fn probes_and_contract_are_public(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let c = &app.client;
    let ok = c.get(app.url("/healthz")).send().await.unwrap();
    assert_eq!(ok.json::<Value>().await.unwrap(), json!({"status": "ok"}));
    let ready = c.get(app.url("/readyz")).send().await.unwrap();
    assert_eq!(ready.status(), StatusCode::OK);
    let spec = c.get(app.url("/openapi.yaml")).send().await.unwrap();
    assert_eq!(spec.headers()["content-type"], "application/yaml");
    assert!(spec.text().await.unwrap().starts_with("openapi: 3.1"));
}

/// The items of a page's JSON body.
fn page_items(body: &[u8]) -> Vec<Value> {
    let page: Value = serde_json::from_slice(body).unwrap();
    page["items"].as_array().unwrap().clone()
}
