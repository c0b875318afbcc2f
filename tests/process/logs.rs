//! The log writer: a reader of standard error that stops reading does not
//! stop the service; lines past the queue are dropped and counted, and what
//! was queued is written out when the server stops.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use serde_json::Value;

use accelcal_testkit::process::ADMIN;

/// Requests sent while nobody reads the log: more than the pipe (64 KiB),
/// the writer's buffer (64 KiB) and the queue (16 384 lines) hold, since
/// each writes one line of a few hundred bytes.
const REQUESTS: usize = 20_000;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_log_reader_does_not_stall_the_service() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["serve", "--listen", "127.0.0.1:0", "--log-format", "json"])
        .args(["--metrics-listen", "127.0.0.1:0", "--database"])
        .arg(dir.path().join("a.db"))
        .env("ACCELCAL_ADMIN_TOKEN", ADMIN)
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Read the log only until both listeners are up, then stop reading
    // (the pipe stays open).
    let mut log = BufReader::new(child.stderr.take().unwrap());
    let (mut base, mut metrics) = (None, None);
    let mut line = String::new();
    while base.is_none() || metrics.is_none() {
        line.clear();
        assert!(log.read_line(&mut line).unwrap() > 0, "the server exited");
        let v: Value = serde_json::from_str(&line).unwrap_or_default();
        let address = v["address"].as_str().map(|a| format!("http://{a}"));
        match v["message"].as_str() {
            Some("accelcal listening") => base = address,
            Some("metrics listening") => metrics = address,
            _ => {}
        }
    }
    let (base, metrics) = (base.unwrap(), metrics.unwrap());

    // Every request is answered although its log line cannot be written:
    // a writer in the request path would block on the full pipe and the
    // requests would time out.
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(20))
        .build()
        .unwrap();
    let tasks: Vec<_> = (0..8)
        .map(|_| {
            let (client, base) = (client.clone(), base.clone());
            tokio::spawn(async move {
                for _ in 0..REQUESTS / 8 {
                    let res = client
                        .get(format!("{base}/v1/sensors"))
                        .bearer_auth(ADMIN)
                        .send()
                        .await
                        .expect("answered while the log is not read");
                    assert_eq!(res.status(), 200);
                }
            })
        })
        .collect();
    for t in tasks {
        t.await.unwrap();
    }
    let text = client
        .get(format!("{metrics}/metrics"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    let dropped: f64 = text
        .lines()
        .find_map(|l| l.strip_prefix("accelcal_log_lines_dropped_total "))
        .expect("the dropped lines are a metric")
        .parse()
        .unwrap();
    // At least what exceeded the pipe, buffer and queue was dropped, and
    // never more lines than were logged.
    assert!(dropped >= 1.0, "{dropped} lines dropped");
    assert!(
        dropped < REQUESTS as f64,
        "{dropped} of {REQUESTS} lines dropped"
    );

    // Read again: every line not dropped arrives, the queue's included.
    let (tx, rx) = std::sync::mpsc::channel::<Value>();
    let reader = std::thread::spawn(move || {
        for line in log.lines().map_while(Result::ok) {
            let _ = tx.send(serde_json::from_str(&line).expect("whole JSON lines"));
        }
    });
    let is_request = |v: &Value| v["message"] == "request" && v["status"] == 200;
    let mut requests = 0;
    while (requests as f64) + dropped < REQUESTS as f64 {
        let v = rx
            .recv_timeout(Duration::from_secs(30))
            .unwrap_or_else(|_| panic!("{requests} request lines written, {dropped} dropped"));
        requests += usize::from(is_request(&v));
    }
    assert!(requests <= REQUESTS, "{requests} request lines");
    assert!(
        requests >= 16_384,
        "the queue's lines are written after the stall: {requests}"
    );

    // Stopped, the server writes out what it still holds, ending with its
    // last line, and exits cleanly.
    // SAFETY: kill(2) with a valid signal number on our own child.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) },
        0
    );
    let status = child.wait().unwrap();
    assert!(status.success(), "{status}");
    reader.join().unwrap();
    let last = rx.try_iter().last().map(|v| v["message"].clone());
    assert_eq!(last, Some(Value::from("database closed; bye")));
}
