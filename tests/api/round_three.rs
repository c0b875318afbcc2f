//! Hardening round three: one test per class of what an outsider on
//! loopback (with, where needed, a reader or station token) found (issue
//! "Hardening, round three", findings 1–11), over real HTTP or raw TCP.

use std::time::Duration;

use reqwest::StatusCode;
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

async fn connect(app: &TestApp) -> TcpStream {
    TcpStream::connect(app.base.trim_start_matches("http://"))
        .await
        .unwrap()
}

/// Reads what the server answered within `limit` (the connection may stay open).
async fn answer_within(s: &mut TcpStream, limit: Duration) -> String {
    let mut buf = vec![0u8; 4096];
    let mut got = Vec::new();
    let deadline = tokio::time::Instant::now() + limit;
    while !String::from_utf8_lossy(&got).contains("\r\n\r\n") {
        match tokio::time::timeout_at(deadline, s.read(&mut buf)).await {
            Ok(Ok(0)) | Err(_) | Ok(Err(_)) => break,
            Ok(Ok(n)) => got.extend_from_slice(&buf[..n]),
        }
    }
    String::from_utf8_lossy(&got).into_owned()
}

/// Headers of a 4 MiB body, then nothing: a socket that would hold 4 MiB of
/// the body budget until the body deadline.
fn idle_head(path: &str, token: Option<&str>) -> String {
    let auth = token.map_or(String::new(), |t| format!("Authorization: Bearer {t}\r\n"));
    format!(
        "POST {path} HTTP/1.1\r\nHost: x\r\n{auth}Content-Type: application/json\r\n\
         Content-Length: 4194304\r\n\r\n{{"
    )
}

/// Finding 1: sixteen idle sockets without a token hold none of the body
/// budget (each is answered 401 at once); a token holder holds at most its
/// share (a quarter of the budget), so submissions, `/v1/fuse` and
/// readiness stay green.
#[tokio::test]
async fn bodies_without_a_token_hold_no_budget_and_one_token_only_its_share() {
    let app = TestApp::spawn(Sqlite).await;
    let station = app.token("station", None).await;
    let mut idle = Vec::new();
    for path in ["/v1/calibrations", "/v1/fuse"].repeat(8) {
        let mut s = connect(&app).await;
        s.write_all(idle_head(path, None).as_bytes()).await.unwrap();
        let answer = answer_within(&mut s, Duration::from_secs(2)).await;
        assert!(answer.starts_with("HTTP/1.1 401"), "{answer}");
        idle.push(s);
    }
    assert_eq!(
        app.admission.bodies.available_permits(),
        app.admission.body_budget_kib,
        "no budget is held for a body without a token"
    );
    // One token: its share (64 MiB of 256) is sixteen 4 MiB bodies; one more is 503.
    let share = app.admission.share_kib;
    assert_eq!(share, app.admission.body_budget_kib / 4);
    for _ in 0..share / 4096 {
        let mut s = connect(&app).await;
        s.write_all(idle_head("/v1/fuse", Some(&station)).as_bytes())
            .await
            .unwrap();
        idle.push(s);
    }
    eventually(Duration::from_secs(5), "the share to be taken", || async {
        (app.admission.bodies.available_permits() == app.admission.body_budget_kib - share)
            .then_some(())
    })
    .await;
    let mut fifth = connect(&app).await;
    fifth
        .write_all(idle_head("/v1/fuse", Some(&station)).as_bytes())
        .await
        .unwrap();
    let answer = answer_within(&mut fifth, Duration::from_secs(2)).await;
    assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
    assert!(answer.contains("may have at most"), "{answer}");
    // Everyone else is served, and the replica stays in the load balancer.
    let other = app.token("station", None).await;
    app.submit(&other, &submission("SHARE-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let res = app
        .post("/v1/fuse", ADMIN, &json!({"values": {"k0": [1, 2, 3, 4]}}))
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let ready = app.client.get(app.url("/readyz")).send().await.unwrap();
    assert_eq!(ready.status(), StatusCode::OK);
    drop(idle);
}

async fn post_gzip(app: &TestApp, path: &str, ct: &str, body: Vec<u8>) -> reqwest::Response {
    app.client
        .post(app.url(path))
        .bearer_auth(ADMIN)
        .header("content-type", ct)
        .header("content-encoding", "gzip")
        .body(body)
        .send()
        .await
        .unwrap()
}

/// A gzip body is charged to the budget with its decoded size, not only
/// its size as sent: a token holding half its share with an idle body, whose
/// few KiB of gzip decode to more than the other half, is answered 503 —
/// and with that idle body gone, the same request is taken.
#[tokio::test]
async fn a_gzip_body_is_charged_its_decoded_size() {
    let app = TestApp::configured(Sqlite, |config| {
        config.limits.max_body_bytes = 1024 * 1024;
        config.limits.body_budget_bytes = 1024 * 1024;
    })
    .await;
    assert_eq!(app.admission.share_kib, 1024);
    // 600 KiB of spaces and `{}`: valid JSON, some 1 KiB compressed.
    let mut plain = vec![b' '; 600 * 1024];
    plain.extend_from_slice(br#"{"values": {"k0": [1, 2, 3, 4]}}"#);
    let body = gzip(&plain);
    assert!(body.len() < 4096);
    let mut idle = connect(&app).await;
    idle.write_all(
        format!(
            "POST /v1/fuse HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
             Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{{",
            512 * 1024
        )
        .as_bytes(),
    )
    .await
    .unwrap();
    eventually(
        Duration::from_secs(5),
        "half the share to be taken",
        || async { (app.admission.bodies.available_permits() == 512).then_some(()) },
    )
    .await;
    let res = post_gzip(&app, "/v1/fuse", "application/json", body.clone()).await;
    let p = problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("may have at most 1024 KiB"),
        "{p}"
    );
    drop(idle);
    eventually(
        Duration::from_secs(5),
        "the share to be returned",
        || async { (app.admission.bodies.available_permits() == 1024).then_some(()) },
    )
    .await;
    let res = post_gzip(&app, "/v1/fuse", "application/json", body).await;
    assert_eq!(res.status(), StatusCode::OK);
}

/// Finding 2: a gzip body of two members (concatenated `.gz` files) is
/// decoded whole — all six runs stored, the stored submission the whole
/// text — and bytes after the last member are refused, not dropped.
#[tokio::test]
async fn every_gzip_member_is_decoded_and_trailing_bytes_are_refused() {
    let app = TestApp::spawn(Sqlite).await;
    let csv = paper_csv();
    // Cut before run 5's first row: runs 1–4 in one member, 5–6 in another.
    let cut = csv
        .lines()
        .scan(0, |at, line| {
            let start = *at;
            *at += line.len() + 1;
            Some((start, line))
        })
        .find(|(_, line)| line.starts_with("5,"))
        .map(|(start, _)| start)
        .expect("a row of run 5");
    let mut two = gzip(&csv.as_bytes()[..cut]);
    two.extend(gzip(&csv.as_bytes()[cut..]));
    let res = post_gzip(&app, "/v1/calibrations", "text/csv", two).await;
    let status = res.status();
    let doc: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{doc}");
    assert_eq!(doc["runs"].as_array().unwrap().len(), 6, "{doc}");
    let id = doc["id"].as_str().unwrap();
    let stored = app
        .get(&format!("/v1/calibrations/{id}/submission"), ADMIN)
        .await
        .text()
        .await
        .unwrap();
    assert_eq!(stored, csv, "the whole text is stored, byte for byte");

    let plain = serde_json::to_vec(&paper()).unwrap();
    for trailer in [b"garbage".to_vec(), vec![0u8; 16], gzip(b"")[..5].to_vec()] {
        let mut body = gzip(&plain);
        body.extend(&trailer);
        let res = post_gzip(&app, "/v1/calibrations", "application/json", body).await;
        let p = problem(res, StatusCode::BAD_REQUEST).await;
        assert!(p["detail"].as_str().unwrap().contains("gzip"), "{p}");
    }
    // Nothing but the six-run calibration was stored.
    let history = app.get("/v1/sensors/PAPER-2005/calibrations", ADMIN).await;
    assert_eq!(history.status(), StatusCode::NOT_FOUND);
}

/// Finding 9: failed authentications are throttled per client address —
/// after a burst of 20 the address gets 429 with `Retry-After` without its
/// credential being looked up — while a token holder is not locked out:
/// the configured admin token and tokens that authenticated since the start
/// are still judged and served.
#[tokio::test]
async fn failed_authentications_are_throttled_without_locking_out_holders() {
    let app = TestApp::spawn(Sqlite).await;
    let reader = app.token("reader", None).await;
    assert_eq!(
        app.get("/v1/sensors", &reader).await.status(),
        StatusCode::OK
    );
    let unused = app.token("reader", None).await;
    let guess = format!("acc_{}_{}", "0".repeat(32), "A".repeat(43));
    for _ in 0..20 {
        let res = app.get("/v1/sensors", &guess).await;
        problem(res, StatusCode::UNAUTHORIZED).await;
    }
    let res = app.get("/v1/sensors", &guess).await;
    let retry = res.headers()["retry-after"].to_str().unwrap().to_owned();
    let p = problem(res, StatusCode::TOO_MANY_REQUESTS).await;
    assert_eq!(p["type"], "urn:accelcal:problem:too-many-requests");
    assert!(retry.parse::<u64>().unwrap() >= 1);
    // Holders whose tokens the server has seen work are served at once.
    assert_eq!(app.get("/v1/sensors", ADMIN).await.status(), StatusCode::OK);
    assert_eq!(
        app.get("/v1/sensors", &reader).await.status(),
        StatusCode::OK
    );
    // A wrong secret for a known token is judged (401), not waved through.
    // `acc_`, the id's 32 hex digits and `_` (the secret may hold `_` too).
    let wrong = format!("{}{}", &reader[..37], "B".repeat(43));
    problem(
        app.get("/v1/sensors", &wrong).await,
        StatusCode::UNAUTHORIZED,
    )
    .await;
    // A token never used yet waits, like any unknown credential.
    problem(
        app.get("/v1/sensors", &unused).await,
        StatusCode::TOO_MANY_REQUESTS,
    )
    .await;
}

/// `now` moved by `seconds`, as RFC 3339.
fn now_plus(seconds: i64) -> String {
    let t = time::OffsetDateTime::now_utc() + time::Duration::seconds(seconds);
    t.format(&time::format_description::well_known::Rfc3339)
        .unwrap()
}

/// Finding 5: a `performed_at` more than five minutes ahead of the server's
/// clock is refused, and one within the forgiven skew is recorded as the
/// time it was received, so it cannot outrank a calibration that arrives
/// after it as the sensor's latest.
#[tokio::test]
async fn a_calibration_from_the_future_cannot_pin_the_coefficients() {
    let app = TestApp::spawn(Sqlite).await;
    let station = app.token("station", None).await;
    for ahead in [10 * 60, 23 * 3600] {
        let res = app
            .post(
                "/v1/calibrations",
                &station,
                &submission("FUTURE-1", &now_plus(ahead), 4),
            )
            .await;
        let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
        assert_eq!(pointers(&p), ["/performed_at"], "{p}");
        assert!(
            p["detail"].as_str().unwrap().contains("at most 5 minutes"),
            "{p}"
        );
    }
    let skewed = app
        .submit(&station, &submission("FUTURE-1", &now_plus(4 * 60), 4))
        .await;
    assert_eq!(
        skewed["performed_at"], skewed["received_at"],
        "a forgiven skew is recorded as the time received"
    );
    let honest = app
        .submit(&station, &submission("FUTURE-1", &now_plus(0), 4))
        .await;
    let served = app
        .get_json("/v1/sensors/FUTURE-1/coefficients", &station)
        .await;
    assert_eq!(served["calibration_id"], honest["id"], "{served}");
}

/// Finding 6: a station may name a sensor's current type, or any type while
/// the sensor has none, but not re-type it — not even in a back-dated
/// submission; an admin may.
#[tokio::test]
async fn a_station_cannot_retype_a_sensor_through_a_submission() {
    let app = TestApp::spawn(Sqlite).await;
    let mut nav: Value =
        serde_json::from_str(include_str!("../../examples/sensor-type-nav.json")).unwrap();
    // The submissions below are in mA.
    nav["unit"] = json!("mA");
    let mut lenient = nav.clone();
    lenient["limits"] = json!({"k0": {"min": -1, "max": 1}});
    lenient["interval_days"] = json!(3650);
    for (id, t) in [("NAV", &nav), ("LENIENT", &lenient)] {
        let res = app
            .client
            .put(app.url(&format!("/v1/sensor-types/{id}")))
            .bearer_auth(ADMIN)
            .json(t)
            .send()
            .await
            .unwrap();
        assert!(res.status().is_success(), "{}", res.status());
    }
    let station = app.token("station", None).await;
    let typed = |at: &str, t: &str| {
        let mut s = submission("TYPED-1", at, 4);
        s["sensor_type"] = json!(t);
        s
    };
    app.submit(&station, &typed("2026-01-01T00:00:00Z", "NAV"))
        .await;
    for at in ["2026-02-01T00:00:00Z", "2025-01-01T00:00:00Z"] {
        let res = app
            .post("/v1/calibrations", &station, &typed(at, "LENIENT"))
            .await;
        let p = problem(res, StatusCode::FORBIDDEN).await;
        assert_eq!(pointers(&p), ["/sensor_type"], "{p}");
        assert!(p["detail"].as_str().unwrap().contains("`NAV`"), "{p}");
    }
    app.submit(&station, &typed("2026-03-01T00:00:00Z", "NAV"))
        .await;
    let sensor = app.get_json("/v1/sensors/TYPED-1", &station).await;
    assert_eq!(sensor["sensor_type"], "NAV", "{sensor}");
    assert_eq!(sensor["calibration_count"], 2, "{sensor}");
    app.submit(ADMIN, &typed("2026-04-01T00:00:00Z", "LENIENT"))
        .await;
    let sensor = app.get_json("/v1/sensors/TYPED-1", &station).await;
    assert_eq!(sensor["sensor_type"], "LENIENT", "{sensor}");
}

/// Finding 3: a backup moved over the live SQLite file is not served by the
/// running service — nothing of either file is answered from memory: the
/// coefficients, a token, a submission and readiness are all 503 naming the
/// replacement — and, restarted, the service serves the restored file
/// (its counts, its latest calibration, its tokens). The backup itself is
/// taken through the service (`GET /v1/backup`), the only way while it runs.
#[tokio::test]
async fn a_replaced_database_file_is_refused_until_restart() {
    let mut app = TestApp::spawn(Sqlite).await;
    let station = app.token("station", None).await;
    let first = app
        .submit(&station, &submission("SWAP-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let res = app.get("/v1/backup", &station).await;
    problem(res, StatusCode::FORBIDDEN).await;
    let res = app.get("/v1/backup", ADMIN).await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.headers()["content-type"], "application/vnd.sqlite3");
    let copy = res.bytes().await.unwrap();
    assert!(copy.starts_with(b"SQLite format 3\0"));
    let backup = format!("{}.backup", app.db_path().display());
    std::fs::write(&backup, &copy).unwrap();
    let leftovers = std::fs::read_dir(app.db_path().parent().unwrap())
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(".accelcal-backup-")
        })
        .count();
    assert_eq!(leftovers, 0, "the copy taken for the answer is removed");
    // After the backup: a second calibration and a new token, both cached.
    let second = app
        .submit(&station, &submission("SWAP-1", "2026-02-01T00:00:00Z", 4))
        .await;
    let late = app.token("reader", None).await;
    let coefficients = app.get_json("/v1/sensors/SWAP-1/coefficients", &late).await;
    assert_eq!(coefficients["calibration_id"], second["id"]);
    // The backup is moved over the live file. A write is refused at once;
    // answers from memory once the last good check of the file has lapsed.
    std::fs::rename(&backup, app.db_path()).unwrap();
    let res = app
        .post(
            "/v1/calibrations",
            &station,
            &submission("SWAP-1", "2026-03-01T00:00:00Z", 4),
        )
        .await;
    problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
    tokio::time::sleep(accelcal::store::sqlite::RECHECK + Duration::from_millis(20)).await;
    for (path, token) in [
        ("/v1/sensors/SWAP-1/coefficients", station.as_str()),
        ("/v1/sensors/SWAP-1", station.as_str()),
        ("/v1/sensors", late.as_str()),
    ] {
        let p = problem(app.get(path, token).await, StatusCode::SERVICE_UNAVAILABLE).await;
        assert!(p["detail"].as_str().is_some(), "{path}: {p}");
    }
    let ready = app.client.get(app.url("/readyz")).send().await.unwrap();
    let p = problem(ready, StatusCode::SERVICE_UNAVAILABLE).await;
    assert!(p["detail"].as_str().unwrap().contains("unavailable"), "{p}");
    // Restarted on the restored file: its state, whole.
    let db = app.take_database().unwrap();
    app.stop().await;
    // A stale WAL of the replaced file must not be paired with the backup.
    let _ = std::fs::remove_file(format!("{}-wal", db.url));
    let app = TestApp::spawn_on(&db.url).await;
    let sensor = app.get_json("/v1/sensors/SWAP-1", &station).await;
    assert_eq!(sensor["calibration_count"], 1, "{sensor}");
    let coefficients = app
        .get_json("/v1/sensors/SWAP-1/coefficients", &station)
        .await;
    assert_eq!(coefficients["calibration_id"], first["id"]);
    problem(
        app.get("/v1/sensors", &late).await,
        StatusCode::UNAUTHORIZED,
    )
    .await;
    let third = app
        .submit(&station, &submission("SWAP-1", "2026-03-01T00:00:00Z", 4))
        .await;
    assert_eq!(third["as_found"]["previous_calibration_id"], first["id"]);
    drop(db);
}

/// Finding 11: readiness reflects whether the service can accept work — a
/// SQLite database whose disk has less than the configured free space
/// fails `/readyz` (saying so), while the process stays up; with room, it
/// passes. Judged against the disk's real free space (`statvfs`).
#[tokio::test]
async fn readiness_fails_when_the_disk_has_no_room() {
    let dir = tempfile::tempdir().unwrap();
    let st = rustix::fs::statvfs(dir.path()).unwrap();
    let free = st.f_bavail * st.f_frsize;
    for (min_free, ready) in [(free + (1 << 30), false), (free / 2, true)] {
        let app = TestApp::configured(Sqlite, |c| c.min_free_disk_bytes = min_free).await;
        let res = app.client.get(app.url("/readyz")).send().await.unwrap();
        if ready {
            assert_eq!(res.status(), StatusCode::OK);
        } else {
            let p = problem(res, StatusCode::SERVICE_UNAVAILABLE).await;
            assert!(p["detail"].as_str().unwrap().contains("unavailable"), "{p}");
            let health = app.client.get(app.url("/healthz")).send().await.unwrap();
            assert_eq!(health.status(), StatusCode::OK);
        }
    }
}
