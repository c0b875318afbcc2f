//! Hardening round two: one test per class of what an attack with reader and
//! station tokens found (issue "Hardening, round two", findings 1–14), over
//! real HTTP or raw TCP.

use std::time::{Duration, Instant};

use reqwest::StatusCode;
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

async fn post_body(
    app: &TestApp,
    path: &str,
    token: &str,
    ct: &str,
    body: Vec<u8>,
) -> reqwest::Response {
    app.client
        .post(app.url(path))
        .bearer_auth(token)
        .header("content-type", ct)
        .body(body)
        .send()
        .await
        .unwrap()
}

/// Sends raw bytes and reads the whole answer.
async fn raw(app: &TestApp, request: &[u8]) -> String {
    let mut s = TcpStream::connect(app.base.trim_start_matches("http://"))
        .await
        .unwrap();
    s.write_all(request).await.unwrap();
    let mut buf = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(10), s.read_to_end(&mut buf)).await;
    String::from_utf8_lossy(&buf).into_owned()
}

fn body_of(answer: &str) -> Value {
    let (_, body) = answer.split_once("\r\n\r\n").unwrap();
    serde_json::from_str(body).unwrap_or_else(|e| panic!("{e}: {answer}"))
}

/// Findings 1 and 2: a CSV naming a new run and a new angle on every row
/// is refused after reading no more than the limits allow, with one short
/// error — not an answer growing with the square of the input.
#[tokio::test]
async fn csv_with_every_row_new_is_refused_small_and_fast() {
    let app = TestApp::spawn(Sqlite).await;
    for rows in [700usize, 40_000] {
        let mut csv = String::from("run,angle_deg,output\n");
        for k in 0..rows {
            csv += &format!("r{k},{}.25,1\n", k % 3500);
        }
        let res = post_body(&app, "/v1/identify", ADMIN, "text/csv", csv.into_bytes()).await;
        let text = res.text().await.unwrap();
        assert!(text.len() < 4096, "{} bytes", text.len());
        let p: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(p["status"], 422);
        assert!(
            p["errors"][0]["detail"]
                .as_str()
                .unwrap()
                .contains("beyond the 360 accepted"),
            "{p}"
        );
    }
}

/// Finding 2: heavy CSV conversion runs off the async workers; health
/// answers while two 4 MB CSVs are converted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_answers_while_heavy_bodies_are_converted() {
    let app = TestApp::spawn(Sqlite).await;
    let mut csv = String::from("run,angle_deg,output\n");
    while csv.len() < 3_900_000 {
        let k = csv.len();
        csv += &format!("r{},{}.5,{}\n", k % 7, k % 359, k % 1000);
    }
    let mut heavy = Vec::new();
    for _ in 0..2 {
        let client = app.client.clone();
        let url = app.url("/v1/identify");
        let body = csv.clone();
        heavy.push(tokio::spawn(async move {
            client
                .post(url)
                .bearer_auth(ADMIN)
                .header("content-type", "text/csv")
                .body(body)
                .send()
                .await
                .unwrap()
                .status()
        }));
    }
    for _ in 0..5 {
        let res = tokio::time::timeout(
            Duration::from_secs(5),
            app.client.get(app.url("/healthz")).send(),
        )
        .await
        .expect("health answered while heavy bodies were converted")
        .unwrap();
        assert_eq!(res.status(), StatusCode::OK);
    }
    for h in heavy {
        assert!(h.await.unwrap().is_client_error());
    }
}

/// Finding 3: two million faulty samples give the first hundred errors and
/// a count, in an answer of a few kilobytes.
#[tokio::test]
async fn error_lists_are_capped_and_counted() {
    let app = TestApp::spawn(Sqlite).await;
    let positions: Vec<Value> = (0..360).map(|k| json!({"angle_deg": k})).collect();
    let samples = format!("[{}]", vec!["\"\""; 1000].join(","));
    let readings = format!("[{}]", vec![samples.as_str(); 360].join(","));
    let runs = format!(
        "[{}]",
        vec![format!("{{\"readings\": {readings}}}"); 6].join(",")
    );
    let body = format!(
        "{{\"sensor_id\": \"A\", \"positions\": {}, \"runs\": {runs}}}",
        serde_json::to_string(&positions).unwrap()
    );
    assert!(body.len() > 6_000_000);
    let res = post_body(
        &app,
        "/v1/identify",
        ADMIN,
        "application/json",
        body.into_bytes(),
    )
    .await;
    let text = res.text().await.unwrap();
    assert!(text.len() < 20_000, "{} bytes", text.len());
    let p: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(p["errors"].as_array().unwrap().len(), 100);
    // Every sample is wrong, and so is their total (past 2 000 000).
    assert_eq!(p["errors_omitted"], 360 * 6 * 1000 + 1 - 100);
    assert_eq!(p["errors"][0]["pointer"], "/runs/0/readings/0/0");
    // Unknown keys in a fusion: one error, the key cut short.
    let mut values = serde_json::Map::new();
    for k in 0..5000 {
        values.insert(format!("t{k}{}", "x".repeat(100)), json!([1, 2]));
    }
    let res = app
        .post("/v1/fuse", ADMIN, &json!({"values": values}))
        .await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(p.to_string().len() < 2000);
}

/// Finding 5: outputs of 1e-152 are calibrated to the scaled values (not
/// stored as null), their coefficients can be used for compensation, and
/// fusion of tiny given values works.
#[tokio::test]
async fn tiny_outputs_calibrate_and_fuse_instead_of_overflowing() {
    let app = TestApp::spawn(Sqlite).await;
    let mut body = paper();
    let base = app
        .post("/v1/identify", ADMIN, &body)
        .await
        .json::<Value>()
        .await
        .unwrap();
    for run in body["runs"].as_array_mut().unwrap() {
        for samples in run["readings"].as_array_mut().unwrap() {
            for x in samples.as_array_mut().unwrap() {
                *x = json!(x.as_f64().unwrap() * 1e-152);
            }
        }
    }
    let stored = app.submit(ADMIN, &body).await;
    for t in ["k0", "ki", "kp"] {
        for part in ["coefficients", "std_errors"] {
            let got = stored["fused"][part][t].as_f64().unwrap();
            let want = base["fused"][part][t].as_f64().unwrap() * 1e-152;
            assert!(
                (got - want).abs() <= 1e-9 * want.abs(),
                "{part} {t}: {got:e} vs {want:e}"
            );
        }
    }
    let ki = stored["fused"]["coefficients"]["ki"].as_f64().unwrap();
    let k0 = stored["fused"]["coefficients"]["k0"].as_f64().unwrap();
    let res = app
        .post(
            "/v1/sensors/PAPER-2005/compensate",
            ADMIN,
            &json!({"outputs": [k0 + ki * 0.5]}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let a = res.json::<Value>().await.unwrap()["a_i"][0]
        .as_f64()
        .unwrap();
    assert!((a - 0.5).abs() < 1e-9, "{a}");
    let f: Value = app
        .post(
            "/v1/fuse",
            ADMIN,
            &json!({"values": {"k0": [0, 2e-160, 0, 2e-160]}}),
        )
        .await
        .json()
        .await
        .unwrap();
    close(&f["fused"]["coefficients"]["k0"], 1e-160, 1e-175);
    close(
        &f["fused"]["std_errors"]["k0"],
        1e-160 / 2f64.sqrt(),
        1e-175,
    );
    let res = app
        .post(
            "/v1/fuse",
            ADMIN,
            &json!({"values": {"k0": [1e-300, 2e-300, 3e-300, 4e-300]}}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
}

/// Finding 6: after the header every line is data — a label or run
/// starting with `#` is kept — and an unknown metadata key is refused.
#[tokio::test]
async fn csv_rows_starting_with_a_hash_are_data() {
    let app = TestApp::spawn(Sqlite).await;
    let plain = paper_csv();
    let mut hashed = String::new();
    for (n, line) in plain.lines().enumerate() {
        if line.starts_with('#') || line.starts_with("test") {
            hashed += line;
        } else if n > 0 {
            // The run named `#<test>`.
            hashed += &format!("#{line}");
        }
        hashed.push('\n');
    }
    let a: Value = post_body(&app, "/v1/identify", ADMIN, "text/csv", plain.into_bytes())
        .await
        .json()
        .await
        .unwrap();
    let res = post_body(&app, "/v1/identify", ADMIN, "text/csv", hashed.into_bytes()).await;
    assert_eq!(res.status(), StatusCode::OK);
    let b: Value = res.json().await.unwrap();
    assert_eq!(a["fused"], b["fused"]);
    assert_eq!(b["runs"].as_array().unwrap().len(), 6);
    let res = post_body(
        &app,
        "/v1/calibrations",
        ADMIN,
        "text/csv",
        b"# Station ID: LAB-9\nrun,angle_deg,output\n1,0,1\n".to_vec(),
    )
    .await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .contains("unknown field `Station ID`"),
        "{p}"
    );
}

/// Finding 7: what the HTTP library refuses before routing is a problem.
#[tokio::test]
async fn errors_before_routing_are_problems() {
    let app = TestApp::spawn(Sqlite).await;
    let huge = format!(
        "GET /healthz HTTP/1.1\r\nHost: x\r\nX-Big: {}\r\n\r\n",
        "a".repeat(300_000)
    );
    let answer = raw(&app, huge.as_bytes()).await;
    assert!(answer.starts_with("HTTP/1.1 431"), "{answer}");
    assert!(
        answer
            .to_ascii_lowercase()
            .contains("content-type: application/problem+json"),
        "{answer}"
    );
    assert_eq!(body_of(&answer)["status"], 431);
    let answer = raw(&app, b"GARBAGE\r\n\r\n").await;
    assert!(answer.starts_with("HTTP/1.1 400"), "{answer}");
    let p = body_of(&answer);
    assert_eq!(p["type"], "urn:accelcal:problem:malformed");
    assert!(p["request_id"].is_string());
    // A bad chunk size: a problem, with no library text.
    let answer = raw(
        &app,
        format!(
            "POST /v1/fuse HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
             Content-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n{{}}\r\n0\r\n\r\n"
        )
        .as_bytes(),
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 400"), "{answer}");
    let detail = body_of(&answer)["detail"].as_str().unwrap().to_owned();
    assert!(!detail.contains("chunk size line"), "{detail}");
}

/// Finding 8: gzip bodies are decompressed (the limit applies after), other
/// encodings are 415, transfer codings other than chunked 501.
#[tokio::test]
async fn gzip_bodies_are_accepted_and_bounded() {
    let app = TestApp::spawn(Sqlite).await;
    let plain = serde_json::to_vec(&paper()).unwrap();
    let res = app
        .client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(ADMIN)
        .header("content-type", "application/json")
        .header("content-encoding", "gzip")
        .body(gzip(&plain))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::CREATED);
    let id = res.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let stored = app
        .get(&format!("/v1/calibrations/{id}/submission"), ADMIN)
        .await
        .bytes()
        .await
        .unwrap();
    assert_eq!(
        &stored[..],
        &plain[..],
        "the submission is stored decompressed"
    );
    // 65 MiB of spaces compress to some 65 kB: refused once decompressed.
    let bomb = gzip(&vec![b' '; 65 * 1024 * 1024]);
    assert!(bomb.len() < 200_000);
    let res = app
        .client
        .post(app.url("/v1/identify"))
        .bearer_auth(ADMIN)
        .header("content-type", "application/json")
        .header("content-encoding", "gzip")
        .body(bomb)
        .send()
        .await
        .unwrap();
    problem(res, StatusCode::PAYLOAD_TOO_LARGE).await;
    let res = app
        .client
        .post(app.url("/v1/identify"))
        .bearer_auth(ADMIN)
        .header("content-type", "application/json")
        .header("content-encoding", "br")
        .body(plain.clone())
        .send()
        .await
        .unwrap();
    problem(res, StatusCode::UNSUPPORTED_MEDIA_TYPE).await;
    let answer = raw(
        &app,
        format!(
            "POST /v1/identify HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
             Content-Type: application/json\r\nTransfer-Encoding: gzip, chunked\r\nConnection: close\r\n\r\n2\r\n{{}}\r\n0\r\n\r\n"
        )
        .as_bytes(),
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 501"), "{answer}");
    assert_eq!(
        body_of(&answer)["type"],
        "urn:accelcal:problem:not-implemented"
    );
}

/// Finding 9: two Authorization headers are refused, not resolved.
#[tokio::test]
async fn two_authorization_headers_are_refused() {
    let app = TestApp::spawn(Sqlite).await;
    let reader = app.token("reader", None).await;
    let answer = raw(
        &app,
        format!(
            "GET /v1/sensors HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {reader}\r\n\
             Authorization: Bearer {ADMIN}\r\nConnection: close\r\n\r\n"
        )
        .as_bytes(),
    )
    .await;
    assert!(answer.starts_with("HTTP/1.1 400"), "{answer}");
    assert_eq!(body_of(&answer)["parameter"], "Authorization");
}

/// Findings 10 and 11: a pasted token is never echoed, and what errors echo
/// of the client's input is bounded.
#[tokio::test]
async fn pasted_tokens_are_redacted_and_echoes_bounded() {
    let app = TestApp::spawn(Sqlite).await;
    let token = app.token("reader", None).await;
    // `acc_<id>_<secret>`: the base64url secret may itself hold `_`.
    let secret = token.splitn(3, '_').nth(2).unwrap().to_owned();
    assert_eq!(secret.len(), 43, "{token}");
    let res = app
        .client
        .delete(app.url(&format!("/v1/tokens/{token}")))
        .bearer_auth(ADMIN)
        .send()
        .await
        .unwrap();
    let p = problem(res, StatusCode::NOT_FOUND).await;
    assert!(!p.to_string().contains(&secret), "{p}");
    let res = app
        .client
        .get(app.url("/healthz"))
        .header("x-request-id", token.as_str())
        .send()
        .await
        .unwrap();
    assert!(
        !res.headers()["x-request-id"]
            .to_str()
            .unwrap()
            .contains(&secret)
    );
    let name = "q".repeat(60_000);
    let res = app.get(&format!("/v1/sensors?{name}=1"), ADMIN).await;
    let text = res.text().await.unwrap();
    assert!(text.len() < 1000, "{} bytes", text.len());
    let id = "z".repeat(5000);
    let res = app.get(&format!("/v1/calibrations/{id}"), ADMIN).await;
    let text = res.text().await.unwrap();
    assert!(text.len() < 1000, "{} bytes", text.len());
}

/// Finding 12: a station-bound token may not compute as another station,
/// on identify as on submit; an unbound one may name any.
#[tokio::test]
async fn identify_and_submit_agree_on_bound_stations() {
    let app = TestApp::spawn(Sqlite).await;
    let bound = app.token("station", Some("LAB-1")).await;
    let unbound = app.token("station", None).await;
    let mut body = paper();
    body["station_id"] = json!("LAB-2");
    for path in ["/v1/identify", "/v1/calibrations"] {
        problem(app.post(path, &bound, &body).await, StatusCode::FORBIDDEN).await;
    }
    let r: Value = app
        .post("/v1/identify", &unbound, &body)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["station_id"], "LAB-2");
    body["station_id"] = json!("LAB-1");
    let r: Value = app
        .post("/v1/identify", &bound, &body)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["station_id"], "LAB-1");
}

/// Finding 13: spreadsheet CSV (a byte order mark, CR-only line ends) is
/// accepted and stored as sent.
#[tokio::test]
async fn spreadsheet_csv_is_accepted() {
    let app = TestApp::spawn(Sqlite).await;
    let csv = format!("\u{feff}{}", paper_csv().replace('\n', "\r"));
    let res = post_body(
        &app,
        "/v1/calibrations",
        ADMIN,
        "text/csv",
        csv.clone().into_bytes(),
    )
    .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let r: Value = res.json().await.unwrap();
    close(&r["fused"]["coefficients"]["kp"], 0.0062738448, 1e-9);
    let stored = app
        .get(
            &format!("/v1/calibrations/{}/submission", r["id"].as_str().unwrap()),
            ADMIN,
        )
        .await
        .text()
        .await
        .unwrap();
    assert_eq!(stored, csv);
}

/// Finding 14: the database is readable by its owner only.
#[tokio::test]
async fn the_database_is_private() {
    use std::os::unix::fs::PermissionsExt;
    let app = TestApp::spawn(Sqlite).await;
    app.submit(ADMIN, &paper()).await;
    for suffix in ["", "-wal"] {
        let path = format!("{}{suffix}", app.db_path().display());
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600, "{path}");
    }
    // The WAL's index is in the server's memory, never in a shared file.
    let shm = format!("{}-shm", app.db_path().display());
    assert!(!std::path::Path::new(&shm).exists(), "{shm}");
}

/// Timing guard for the quadratic finding: 40 000 new-run rows are refused
/// after the position limit, long before the request deadline (a functional
/// bound: the old conversion took minutes here).
#[tokio::test]
async fn refusal_of_a_hostile_csv_does_not_wait_for_the_deadline() {
    let app = TestApp::spawn(Sqlite).await;
    let mut csv = String::from("run,angle_deg,output\n");
    for k in 0..100_000 {
        csv += &format!("r{k},{k}.5,1\n");
    }
    let start = Instant::now();
    let res = post_body(&app, "/v1/identify", ADMIN, "text/csv", csv.into_bytes()).await;
    assert_eq!(res.status(), StatusCode::UNPROCESSABLE_ENTITY);
    assert!(start.elapsed() < Duration::from_secs(30));
}
