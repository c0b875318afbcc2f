//! Bounded everything: slow clients, oversized and chunked bodies, the
//! concurrency limit — driven over raw TCP where a client library would be
//! too polite.

use std::time::{Duration, Instant};

use accelcal::startup::Config;
use reqwest::StatusCode;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::helpers::*;

async fn strict_app(edit: impl FnOnce(&mut Config)) -> (TestApp, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("a.db");
    let mut config = Config::for_tests(db.to_str().unwrap(), ADMIN);
    config.header_timeout = Duration::from_secs(1);
    config.limits.body_timeout = Duration::from_secs(1);
    config.limits.max_body_bytes = 1024;
    edit(&mut config);
    (TestApp::spawn_with(config, db).await, dir)
}

async fn connect(app: &TestApp) -> TcpStream {
    TcpStream::connect(app.base.trim_start_matches("http://"))
        .await
        .unwrap()
}

/// Reads until the server closes, or gives up after `limit`.
async fn read_all(stream: &mut TcpStream, limit: Duration) -> (String, bool) {
    let mut buf = Vec::new();
    let closed = tokio::time::timeout(limit, stream.read_to_end(&mut buf))
        .await
        .is_ok();
    (String::from_utf8_lossy(&buf).into_owned(), closed)
}

#[tokio::test]
async fn slow_or_silent_headers_are_cut_off() {
    let (app, _dir) = strict_app(|_| {}).await;
    // Half a request line, then nothing.
    let mut s = connect(&app).await;
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n")
        .await
        .unwrap();
    let start = Instant::now();
    let (_, closed) = read_all(&mut s, Duration::from_secs(10)).await;
    assert!(
        closed,
        "a client that never finishes its headers holds the connection"
    );
    assert!(start.elapsed() < Duration::from_secs(8));
    // Connected and silent.
    let mut s = connect(&app).await;
    let (_, closed) = read_all(&mut s, Duration::from_secs(10)).await;
    assert!(closed, "a silent client holds the connection");
}

#[tokio::test]
async fn slow_bodies_get_408() {
    let (app, _dir) = strict_app(|_| {}).await;
    let mut s = connect(&app).await;
    let head = format!(
        "POST /v1/identify HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
         Content-Type: application/json\r\nContent-Length: 500\r\n\r\n{{\"sensor_id\""
    );
    s.write_all(head.as_bytes()).await.unwrap();
    let (answer, _) = read_all(&mut s, Duration::from_secs(10)).await;
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("application/problem+json"), "{answer}");
}

#[tokio::test]
async fn chunked_bodies_stop_at_the_limit() {
    let (app, _dir) = strict_app(|_| {}).await;
    let mut s = connect(&app).await;
    let head = format!(
        "POST /v1/identify HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
         Content-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n"
    );
    s.write_all(head.as_bytes()).await.unwrap();
    let chunk = format!("400\r\n{}\r\n", "x".repeat(0x400));
    let mut answer = String::new();
    // Keep sending 1 KiB chunks; the server must answer 413 after the first
    // kilobyte rather than read on.
    for _ in 0..64 {
        if s.write_all(chunk.as_bytes()).await.is_err() {
            break;
        }
        let mut buf = [0u8; 4096];
        if let Ok(Ok(n)) = tokio::time::timeout(Duration::from_millis(50), s.read(&mut buf)).await {
            answer.push_str(&String::from_utf8_lossy(&buf[..n]));
            break;
        }
    }
    if answer.is_empty() {
        answer = read_all(&mut s, Duration::from_secs(5)).await.0;
    }
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
}

#[tokio::test]
async fn declared_oversize_is_refused_before_the_body_is_sent() {
    let (app, _dir) = strict_app(|_| {}).await;
    let mut s = connect(&app).await;
    let head = format!(
        "POST /v1/identify HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
         Content-Type: application/json\r\nContent-Length: 1000000000\r\n\r\n"
    );
    s.write_all(head.as_bytes()).await.unwrap();
    let mut buf = [0u8; 4096];
    let n = tokio::time::timeout(Duration::from_secs(5), s.read(&mut buf))
        .await
        .unwrap()
        .unwrap();
    assert!(String::from_utf8_lossy(&buf[..n]).starts_with("HTTP/1.1 413"));
}

#[tokio::test]
async fn beyond_the_concurrency_limit_the_answer_is_503_at_once() {
    let (app, _dir) = strict_app(|c| {
        c.limits.max_concurrent = 1;
        c.limits.body_timeout = Duration::from_secs(5);
    })
    .await;
    // Occupy the only slot with a request whose body is still arriving.
    let mut hog = connect(&app).await;
    let head = format!(
        "POST /v1/identify HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
         Content-Type: application/json\r\nContent-Length: 100\r\n\r\n{{"
    );
    hog.write_all(head.as_bytes()).await.unwrap();
    // Once the server has taken the hog in (polled, not assumed after a
    // sleep), the next request is shed at once.
    let deadline = Instant::now() + Duration::from_secs(10);
    let res = loop {
        let start = Instant::now();
        let res = app.get("/v1/sensors", ADMIN).await;
        if res.status() == StatusCode::SERVICE_UNAVAILABLE {
            assert!(
                start.elapsed() < Duration::from_secs(2),
                "the request queued instead of being shed"
            );
            break res;
        }
        assert!(Instant::now() < deadline, "the limit never took effect");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert_eq!(res.headers()["retry-after"], "1");
    problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
    // Probes are exempt.
    let ok = app.client.get(app.url("/healthz")).send().await.unwrap();
    assert_eq!(ok.status(), StatusCode::OK);
    drop(hog);
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(app.get("/v1/sensors", ADMIN).await.status(), StatusCode::OK);
}
