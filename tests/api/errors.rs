//! Every error class answers a problem document naming what is wrong, and
//! none of them stores anything.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

async fn post_raw(
    app: &TestApp,
    path: &str,
    content_type: Option<&str>,
    body: &'static str,
) -> reqwest::Response {
    let mut req = app.client.post(app.url(path)).bearer_auth(ADMIN).body(body);
    if let Some(ct) = content_type {
        req = req.header("content-type", ct);
    }
    req.send().await.unwrap()
}

#[rstest]
#[tokio::test]
async fn malformed_and_mistyped_bodies(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let p = problem(
        post_raw(
            &app,
            "/v1/calibrations",
            Some("application/json"),
            "{\"sensor_id\": ",
        )
        .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("line 1"), "{p}");
    problem(
        post_raw(&app, "/v1/calibrations", Some("text/plain"), "{}").await,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
    )
    .await;
    problem(
        post_raw(&app, "/v1/calibrations", None, "{}").await,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
    )
    .await;
    problem(
        post_raw(&app, "/v1/fuse", Some("text/csv"), "a,b").await,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
    )
    .await;
    let p = problem(
        post_raw(
            &app,
            "/v1/calibrations",
            Some("application/json"),
            r#"{"sensor_id": "a", "sensor_id": "b"}"#,
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .contains("duplicate key `sensor_id`"),
        "{p}"
    );
    assert_eq!(p["errors"][0]["pointer"], "/sensor_id");
}

#[rstest]
#[tokio::test]
async fn validation_lists_every_field(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let mut body = paper();
    body["batchs"] = json!(2);
    body["mount"] = json!("upside-down");
    body["runs"][4]["readings"][2] = json!([1.0, null]);
    let p = problem(
        app.post("/v1/calibrations", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/batchs", "/mount", "/runs/4/readings/2/1"]);
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .contains("unknown field `batchs`")
    );

    let mut body = paper();
    body["model"] = json!(["k0", "ki", "kp", "kii", "kpp"]);
    let p = problem(
        app.post("/v1/calibrations", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/model"]);
    let detail = p["errors"][0]["detail"].as_str().unwrap();
    assert!(detail.contains("k0, kii, kpp"), "{detail}");

    let mut body = paper();
    body["batches"] = json!(4);
    let p = problem(
        app.post("/v1/calibrations", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/batches"]);

    let p = problem(
        app.post("/v1/fuse", ADMIN, &json!({"values": {"k1": [1, 2]}}))
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/values/k1"]);

    // Coefficients with different numbers of runs: the pointer names the
    // one that differs from the first (in model order).
    let p = problem(
        app.post(
            "/v1/fuse",
            ADMIN,
            &json!({"values": {"ki": [1, 2, 3], "k0": [1, 2, 3, 4]}}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/values/ki"]);

    // A batch of identical values cannot be weighted by its variance: the
    // pointer names the coefficient whose fusion failed (kp's first batch
    // of two is 1, 1), not the batches nor the whole map.
    let p = problem(
        app.post(
            "/v1/fuse",
            ADMIN,
            &json!({"values": {"k0": [1, 2, 3, 4], "kp": [1, 1, 3, 4]}}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/values/kp"]);

    let csv = "run,angle_deg,output\n1,0,1.0\n1,90,oops\n";
    let p = problem(
        post_raw(&app, "/v1/calibrations", Some("text/csv"), csv).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .starts_with("CSV line 3"),
        "{p}"
    );

    let sensors: Value = app.get("/v1/sensors", ADMIN).await.json().await.unwrap();
    assert_eq!(
        sensors["items"],
        json!([]),
        "nothing may be stored after refusals"
    );
}

#[rstest]
#[tokio::test]
async fn parameters_paths_and_methods(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    for (query, parameter) in [
        ("limit=0", "limit"),
        ("limit=501", "limit"),
        ("limit=x", "limit"),
        ("after=%%%", "after"),
        ("limt=5", "limt"),
        ("limit=1&limit=2", "limit"),
    ] {
        let p = problem(
            app.get(&format!("/v1/sensors?{query}"), ADMIN).await,
            StatusCode::BAD_REQUEST,
        )
        .await;
        assert_eq!(p["parameter"], parameter, "{query}: {p}");
    }
    let p = problem(
        app.get("/v1/sensors/X/calibrations?from=yesterday", ADMIN)
            .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "from");
    problem(
        app.get("/v1/calibrations/not-a-uuid", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    problem(
        app.get(&format!("/v1/calibrations/{}", uuid::Uuid::now_v7()), ADMIN)
            .await,
        StatusCode::NOT_FOUND,
    )
    .await;
    problem(
        app.get("/v1/nothing-here", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    let res = app
        .client
        .put(app.url("/v1/sensors"))
        .bearer_auth(ADMIN)
        .send()
        .await
        .unwrap();
    assert!(res.headers().contains_key("allow"));
    problem(res, StatusCode::METHOD_NOT_ALLOWED).await;
}

#[rstest]
#[tokio::test]
async fn credentials(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let res = app.client.get(app.url("/v1/sensors")).send().await.unwrap();
    assert_eq!(
        res.headers()["www-authenticate"],
        "Bearer realm=\"accelcal\""
    );
    problem(res, StatusCode::UNAUTHORIZED).await;
    for bad in ["acc_nope", "test-admin-token-012345678", ""] {
        problem(app.get("/v1/sensors", bad).await, StatusCode::UNAUTHORIZED).await;
    }
    let res = app
        .client
        .get(app.url("/v1/sensors"))
        .header("authorization", format!("Basic {ADMIN}"))
        .send()
        .await
        .unwrap();
    problem(res, StatusCode::UNAUTHORIZED).await;
    let reader = app.token("reader", None).await;
    let p = problem(
        app.post("/v1/calibrations", &reader, &paper()).await,
        StatusCode::FORBIDDEN,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("station"), "{p}");
}

/// Over raw TCP, so that it can tell: the 413 arrives while the client has
/// sent only the head, not one byte of the declared body.
#[rstest]
#[tokio::test]
async fn oversized_bodies_are_refused_before_reading(#[values(Sqlite, Postgres)] engine: Engine) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let app = TestApp::configured(engine, |c| c.limits.max_body_bytes = 1024).await;
    let mut s = tokio::net::TcpStream::connect(app.base.trim_start_matches("http://"))
        .await
        .unwrap();
    let head = format!(
        "POST /v1/calibrations HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
         Content-Type: application/json\r\nContent-Length: 4096\r\n\r\n"
    );
    s.write_all(head.as_bytes()).await.unwrap();
    let mut buf = vec![0u8; 8192];
    let n = tokio::time::timeout(std::time::Duration::from_secs(5), s.read(&mut buf))
        .await
        .expect("answered without waiting for the body")
        .unwrap();
    let answer = String::from_utf8_lossy(&buf[..n]);
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    assert!(answer.contains("the limit of 1024 bytes"), "{answer}");
}
