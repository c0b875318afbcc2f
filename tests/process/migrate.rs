//! `accelcal migrate`: a SQLite database copied into PostgreSQL answers
//! every GET exactly as the original does, byte for byte, and a retry of an
//! idempotent submission made before the move is still recognised.

use reqwest::StatusCode;
use serde_json::{Value, json};

use crate::server::{ADMIN, Server};

async fn call(
    c: &reqwest::Client,
    method: reqwest::Method,
    url: String,
    body: Option<(&str, Vec<u8>)>,
    key: Option<&str>,
) -> reqwest::Response {
    let mut req = c.request(method, url).bearer_auth(ADMIN);
    if let Some((content_type, bytes)) = body {
        req = req.header("content-type", content_type).body(bytes);
    }
    if let Some(k) = key {
        req = req.header("idempotency-key", k);
    }
    req.send().await.unwrap()
}

fn migrate(from: &str, to: &str) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["migrate", "--from", from, "--to", to])
        .output()
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_migrated_database_answers_every_get_identically() {
    let dir = tempfile::tempdir().unwrap();
    let sqlite = dir.path().join("before.db");
    let c = reqwest::Client::new();
    let recal = std::fs::read("examples/paper-recalibration.json").unwrap();
    {
        let s = Server::start_with(&sqlite, &[], "info");
        let put = |path: &str, body: Value| {
            call(
                &c,
                reqwest::Method::PUT,
                format!("{}{path}", s.base),
                Some(("application/json", body.to_string().into_bytes())),
                None,
            )
        };
        let post = |body: Vec<u8>, content_type: &'static str, key: Option<&'static str>| {
            call(
                &c,
                reqwest::Method::POST,
                format!("{}/v1/calibrations", s.base),
                Some((content_type, body)),
                key,
            )
        };
        let nav: Value =
            serde_json::from_slice(&std::fs::read("examples/sensor-type-nav.json").unwrap())
                .unwrap();
        assert_eq!(
            put("/v1/sensor-types/NAV", nav).await.status(),
            StatusCode::CREATED
        );
        let paper = std::fs::read("examples/paper-table1.json").unwrap();
        assert_eq!(
            post(paper, "application/json", None).await.status(),
            StatusCode::CREATED
        );
        assert_eq!(
            post(recal.clone(), "application/json", Some("move-1"))
                .await
                .status(),
            StatusCode::CREATED
        );
        let csv = format!(
            "# sensor_id: LATER-1\n# model: k0 ki kp\n{}",
            std::fs::read_to_string("core/tests/data/table1.csv").unwrap()
        );
        assert_eq!(
            post(csv.into_bytes(), "text/csv", None).await.status(),
            StatusCode::CREATED
        );
        assert_eq!(
            put("/v1/sensors/LATER-1", json!({"sensor_type": "NAV"}))
                .await
                .status(),
            StatusCode::OK
        );
        for role in ["reader", "station"] {
            let r = call(
                &c,
                reqwest::Method::POST,
                format!("{}/v1/tokens", s.base),
                Some((
                    "application/json",
                    json!({"role": role, "label": role})
                        .to_string()
                        .into_bytes(),
                )),
                None,
            )
            .await;
            assert_eq!(r.status(), StatusCode::CREATED);
        }
        let tokens: Value = call(
            &c,
            reqwest::Method::GET,
            format!("{}/v1/tokens", s.base),
            None,
            None,
        )
        .await
        .json()
        .await
        .unwrap();
        let first = tokens["items"][0]["id"].as_str().unwrap().to_owned();
        let revoked = call(
            &c,
            reqwest::Method::DELETE,
            format!("{}/v1/tokens/{first}", s.base),
            None,
            None,
        )
        .await;
        assert_eq!(revoked.status(), StatusCode::NO_CONTENT);
        s.terminate();
        let mut s = s;
        assert!(s.child.wait().unwrap().success());
    }

    let pg = crate::pg::TestDb::create().await;
    let from = format!("sqlite:{}", sqlite.display());
    let out = migrate(&from, &pg.url);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let copied: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        copied,
        json!({"sensor_types": 1, "tokens": 2, "calibrations": 3, "typed_sensors": 2, "idempotency_keys": 1})
    );
    let again = migrate(&from, &pg.url);
    assert_eq!(again.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&again.stderr).contains("not empty"));

    let a = Server::start_with(&sqlite, &[], "info");
    let b = Server::start_with(&pg.url, &[], "info");
    let get = |base: &str, path: &str| {
        call(
            &c,
            reqwest::Method::GET,
            format!("{base}{path}"),
            None,
            None,
        )
    };
    let mut paths: Vec<String> = [
        "/v1/sensors",
        "/v1/sensors?status=overdue",
        "/v1/sensors?search=paper",
        "/v1/sensor-types",
        "/v1/sensor-types/NAV",
        "/v1/tokens",
    ]
    .map(String::from)
    .to_vec();
    let sensors: Value = get(&a.base, "/v1/sensors").await.json().await.unwrap();
    for s in sensors["items"].as_array().unwrap() {
        let id = s["sensor_id"].as_str().unwrap();
        for suffix in ["", "/calibrations", "/coefficients", "/stability"] {
            paths.push(format!("/v1/sensors/{id}{suffix}"));
        }
        let history: Value = get(&a.base, &format!("/v1/sensors/{id}/calibrations"))
            .await
            .json()
            .await
            .unwrap();
        for cal in history["items"].as_array().unwrap() {
            let cid = cal["id"].as_str().unwrap();
            paths.push(format!("/v1/calibrations/{cid}"));
            paths.push(format!("/v1/calibrations/{cid}/submission"));
        }
    }
    assert_eq!(paths.len(), 6 + 2 * 4 + 3 * 2);
    for path in &paths {
        let (x, y) = (get(&a.base, path).await, get(&b.base, path).await);
        assert_eq!(
            (x.status(), y.status()),
            (StatusCode::OK, StatusCode::OK),
            "{path}"
        );
        assert_eq!(
            x.headers()["content-type"],
            y.headers()["content-type"],
            "{path}"
        );
        let (x, y) = (x.bytes().await.unwrap(), y.bytes().await.unwrap());
        assert_eq!(x, y, "{path} differs after the move");
    }
    // A station retrying a pre-move submission gets the same calibration.
    let retry = call(
        &c,
        reqwest::Method::POST,
        format!("{}/v1/calibrations", b.base),
        Some(("application/json", recal)),
        Some("move-1"),
    )
    .await;
    assert_eq!(retry.status(), StatusCode::CREATED);
    assert_eq!(retry.headers()["idempotent-replayed"], "true");
}
