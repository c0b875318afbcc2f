//! Every role against every endpoint.

use reqwest::{Method, StatusCode};
use serde_json::{Value, json};

use crate::helpers::*;

/// An operation, the least role it needs and its success status.
struct Op {
    method: Method,
    path: String,
    body: Option<Value>,
    needs: u8,
    ok: StatusCode,
}

const READER: u8 = 1;
const STATION: u8 = 2;
const ADMIN_ROLE: u8 = 3;

async fn operations(app: &TestApp) -> Vec<Op> {
    let r = app
        .submit(ADMIN, &submission("M-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let id = r["id"].as_str().unwrap().to_owned();
    let op = |method: Method, path: &str, body: Option<Value>, needs, ok| Op {
        method,
        path: path.to_owned(),
        body,
        needs,
        ok,
    };
    vec![
        op(
            Method::POST,
            "/v1/calibrations",
            Some(submission("M-2", "2026-01-01T00:00:00Z", 4)),
            STATION,
            StatusCode::CREATED,
        ),
        op(
            Method::GET,
            &format!("/v1/calibrations/{id}"),
            None,
            READER,
            StatusCode::OK,
        ),
        op(
            Method::GET,
            &format!("/v1/calibrations/{id}/submission"),
            None,
            READER,
            StatusCode::OK,
        ),
        op(Method::GET, "/v1/sensors", None, READER, StatusCode::OK),
        op(Method::GET, "/v1/sensors/M-1", None, READER, StatusCode::OK),
        op(
            Method::GET,
            "/v1/sensors/M-1/calibrations",
            None,
            READER,
            StatusCode::OK,
        ),
        op(
            Method::GET,
            "/v1/sensors/M-1/coefficients",
            None,
            READER,
            StatusCode::OK,
        ),
        op(
            Method::POST,
            "/v1/sensors/M-1/compensate",
            Some(json!({"outputs": [0.5]})),
            READER,
            StatusCode::OK,
        ),
        op(
            Method::POST,
            "/v1/identify",
            Some(paper()),
            READER,
            StatusCode::OK,
        ),
        op(
            Method::POST,
            "/v1/fuse",
            Some(json!({"values": {"k0": [1, 2, 4, 7]}})),
            READER,
            StatusCode::OK,
        ),
        op(
            Method::POST,
            "/v1/tokens",
            Some(json!({"role": "reader"})),
            ADMIN_ROLE,
            StatusCode::CREATED,
        ),
        op(Method::GET, "/v1/tokens", None, ADMIN_ROLE, StatusCode::OK),
        op(
            Method::DELETE,
            "/v1/tokens/{victim}",
            None,
            ADMIN_ROLE,
            StatusCode::NO_CONTENT,
        ),
    ]
}

#[tokio::test]
async fn role_matrix() {
    let app = TestApp::spawn().await;
    let tokens = [
        ("none", None, 0u8),
        ("reader", Some(app.token("reader", None).await), READER),
        (
            "station",
            Some(app.token("station", Some("ST-9")).await),
            STATION,
        ),
        ("admin", Some(app.token("admin", None).await), ADMIN_ROLE),
    ];
    for op in operations(&app).await {
        for (name, token, level) in &tokens {
            let path = if op.path.contains("{victim}") {
                let victim: Value = app
                    .post("/v1/tokens", ADMIN, &json!({"role": "reader"}))
                    .await
                    .json()
                    .await
                    .unwrap();
                op.path.replace("{victim}", victim["id"].as_str().unwrap())
            } else {
                op.path.clone()
            };
            let mut req = app.client.request(op.method.clone(), app.url(&path));
            if let Some(t) = token {
                req = req.bearer_auth(t);
            }
            if let Some(b) = &op.body {
                req = req.json(b);
            }
            let res = req.send().await.unwrap();
            let want = match (token, *level >= op.needs) {
                (None, _) => StatusCode::UNAUTHORIZED,
                (Some(_), false) => StatusCode::FORBIDDEN,
                (Some(_), true) => op.ok,
            };
            assert_eq!(res.status(), want, "{name} {} {path}", op.method);
        }
    }
}
