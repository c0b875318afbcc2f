//! Request ids and security headers.

use reqwest::StatusCode;
use serde_json::Value;

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

#[tokio::test]
async fn a_client_request_id_is_kept_and_shown_in_problems() {
    let app = TestApp::spawn(Sqlite).await;
    let res = app
        .client
        .get(app.url("/v1/calibrations/nope"))
        .bearer_auth(ADMIN)
        .header("x-request-id", "station-7:upload-42")
        .send()
        .await
        .unwrap();
    assert_eq!(res.headers()["x-request-id"], "station-7:upload-42");
    let p = problem(res, StatusCode::NOT_FOUND).await;
    assert_eq!(p["request_id"], "station-7:upload-42");
}

#[tokio::test]
async fn unusable_request_ids_are_replaced() {
    let app = TestApp::spawn(Sqlite).await;
    for bad in ["has space", &"x".repeat(200)] {
        let res = app
            .client
            .get(app.url("/healthz"))
            .header("x-request-id", bad)
            .send()
            .await
            .unwrap();
        let id = res.headers()["x-request-id"].to_str().unwrap().to_owned();
        assert_ne!(id, bad);
        assert!(uuid::Uuid::parse_str(&id).is_ok(), "{id}");
    }
    let res = app.client.get(app.url("/healthz")).send().await.unwrap();
    assert!(uuid::Uuid::parse_str(res.headers()["x-request-id"].to_str().unwrap()).is_ok());
}

#[tokio::test]
async fn responses_carry_security_headers() {
    let app = TestApp::spawn(Sqlite).await;
    for res in [
        app.client.get(app.url("/healthz")).send().await.unwrap(),
        app.get("/v1/sensors", ADMIN).await,
        app.get("/v1/nothing", ADMIN).await,
    ] {
        let h = res.headers();
        assert_eq!(h["x-content-type-options"], "nosniff");
        assert_eq!(h["x-frame-options"], "DENY");
        assert_eq!(h["referrer-policy"], "no-referrer");
        assert_eq!(
            h["content-security-policy"],
            "default-src 'none'; frame-ancestors 'none'"
        );
        assert_eq!(h["cross-origin-resource-policy"], "same-origin");
        assert_eq!(h["cache-control"], "no-store");
        // Every header of the list, so that one added to it without its
        // layer is noticed.
        for (name, value) in accelcal::http::stack::SECURITY_HEADERS {
            assert_eq!(h[name], value, "{name}");
        }
        for name in [
            "x-frame-options",
            "content-security-policy",
            "cache-control",
        ] {
            assert_eq!(h.get_all(name).iter().count(), 1, "{name} once");
        }
    }
    // A page sets its own policy (its stylesheet and plots), which is kept,
    // once; the headers it does not set are added.
    let page = app.client.get(app.url("/ui/login")).send().await.unwrap();
    let h = page.headers();
    let csp: Vec<_> = h.get_all("content-security-policy").iter().collect();
    assert_eq!(csp.len(), 1, "{csp:?}");
    assert_ne!(csp[0], "default-src 'none'; frame-ancestors 'none'");
    assert_eq!(h["x-frame-options"], "DENY");
    assert_eq!(h["cross-origin-resource-policy"], "same-origin");
    let res = app
        .post("/v1/tokens", ADMIN, &serde_json::json!({"role": "reader"}))
        .await;
    assert_eq!(
        res.headers()["cache-control"],
        "no-store",
        "secrets must not be cached"
    );
    let _: Value = res.json().await.unwrap();
}
