//! SIGTERM: stop accepting, finish the request in flight, close the
//! database cleanly, exit 0 — and never log a secret.

use std::time::Duration;

use serde_json::Value;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use accelcal_testkit::process::{ADMIN, Server};

#[tokio::test]
async fn sigterm_finishes_in_flight_requests_and_exits_0() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("term.db");
    let mut server = Server::start(&db);
    let client = reqwest::Client::new();

    // A token, used once, so that it has had the chance to reach the log.
    let created: Value = client
        .post(format!("{}/v1/tokens", server.base))
        .bearer_auth(ADMIN)
        .json(&serde_json::json!({"role": "station"}))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let station = created["token"].as_str().unwrap().to_owned();

    // A submission whose body is half sent when SIGTERM arrives.
    let body = include_str!("../../examples/paper-table1.json");
    let (first, rest) = body.split_at(body.len() / 2);
    let mut s = TcpStream::connect(server.base.trim_start_matches("http://"))
        .await
        .unwrap();
    let head = format!(
        "POST /v1/calibrations HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {station}\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    // Observed, not assumed: the server is receiving this body (one more
    // "receiving a request body" than the token request left in the log).
    let receiving = || {
        server
            .log_text()
            .matches("receiving a request body")
            .count()
    };
    let before = receiving();
    s.write_all(head.as_bytes()).await.unwrap();
    s.write_all(first.as_bytes()).await.unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while receiving() == before {
        assert!(
            std::time::Instant::now() < deadline,
            "the body was never taken in"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    server.terminate();

    // No new connections are accepted once the signal is handled (polled).
    let addr = server.base.trim_start_matches("http://").to_owned();
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while TcpStream::connect(&addr).await.is_ok() {
        assert!(
            std::time::Instant::now() < deadline,
            "still accepting connections after SIGTERM"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }

    // …but the one in flight completes.
    s.write_all(rest.as_bytes()).await.unwrap();
    let mut answer = Vec::new();
    tokio::time::timeout(Duration::from_secs(10), s.read_to_end(&mut answer))
        .await
        .unwrap()
        .unwrap();
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 201"), "{answer}");

    let status = tokio::task::spawn_blocking(move || {
        let status = server.child.wait().unwrap();
        (status, server)
    })
    .await
    .unwrap();
    let (status, server) = status;
    assert!(status.success(), "exit status {status:?}");

    // Closed cleanly: the WAL was checkpointed into the database file.
    let wal = dir.path().join("term.db-wal");
    assert!(
        !wal.exists() || std::fs::metadata(&wal).unwrap().len() == 0,
        "WAL left behind"
    );
    let c = rusqlite::Connection::open(&db).unwrap();
    let n: i64 = c
        .query_row("SELECT count(*) FROM calibrations", [], |r| r.get(0))
        .unwrap();
    assert_eq!(n, 1);

    // The log has one line per request, with ids, and no secret.
    let log = server.log_text();
    assert!(log.contains("\"route\":\"/v1/calibrations\""), "{log}");
    assert!(log.contains("request_id"));
    for secret in [ADMIN, station.as_str(), &station[station.len() - 43..]] {
        assert!(!log.contains(secret), "a secret reached the log");
    }
}
