//! `accelcal migrate`: a SQLite database copied into PostgreSQL answers
//! every GET exactly as the original does, byte for byte, and a retry of an
//! idempotent submission made before the move is still recognised.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::process::{ADMIN, Server};

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

/// Migrates, expecting success; what it says it copied.
fn migrated(from: &str, to: &str) -> Value {
    let out = migrate(from, to);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
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
        let stand: Value =
            serde_json::from_slice(&std::fs::read("examples/standard-stand.json").unwrap())
                .unwrap();
        assert_eq!(
            put("/v1/standards/STAND-1", stand).await.status(),
            StatusCode::CREATED
        );
        assert_eq!(
            put(
                "/v1/customers/ACME",
                json!({"name": "Acme Navigation", "due_date_agreed": true})
            )
            .await
            .status(),
            StatusCode::CREATED
        );
        assert_eq!(
            put(
                "/v1/sensors/PAPER-2005/item",
                json!({"serial": "QA-1", "customer": "ACME"})
            )
            .await
            .status(),
            StatusCode::CREATED
        );
        let paper = std::fs::read("examples/paper-table1.json").unwrap();
        let res = post(paper, "application/json", None).await;
        assert_eq!(res.status(), StatusCode::CREATED);
        let paper_id = res.json::<Value>().await.unwrap()["id"].clone();
        let res = post(recal.clone(), "application/json", Some("move-1")).await;
        assert_eq!(res.status(), StatusCode::CREATED);
        let recal_id = res.json::<Value>().await.unwrap()["id"].clone();
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
        // A reviewer approves the paper's calibration and withdraws its
        // recalibration: both signatures come across.
        let reviewer: Value = call(
            &c,
            reqwest::Method::POST,
            format!("{}/v1/tokens", s.base),
            Some((
                "application/json",
                json!({"role": "reviewer", "holder": "Rita Reviewer"})
                    .to_string()
                    .into_bytes(),
            )),
            None,
        )
        .await
        .json()
        .await
        .unwrap();
        for (id, act, body) in [
            (&paper_id, "review", json!({"decision": "approve"})),
            (&recal_id, "withdraw", json!({"reason": "Stand moved."})),
        ] {
            let r = c
                .post(format!(
                    "{}/v1/calibrations/{}/{act}",
                    s.base,
                    id.as_str().unwrap()
                ))
                .bearer_auth(reviewer["token"].as_str().unwrap())
                .json(&body)
                .send()
                .await
                .unwrap();
            assert_eq!(r.status(), StatusCode::OK);
        }
        // A nonconformity of the stand comes across with its record.
        let r = c
            .post(format!("{}/v1/standards/STAND-1/nonconformity", s.base))
            .bearer_auth(ADMIN)
            .json(&json!({"found_at": "2026-11-01T00:00:00Z", "reason": "Found 9″ off."}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), StatusCode::CREATED);
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

    let pg = accelcal_testkit::pg::TestDb::create().await;
    let from = format!("sqlite:{}", sqlite.display());
    let copied = migrated(&from, &pg.url);
    assert_eq!(
        copied,
        json!({"sensor_types": 1, "standards": 1, "customers": 1, "items": 1, "tokens": 3, "calibrations": 3, "signatures": 2, "certificates": 1, "nonconformities": 1, "typed_sensors": 2, "idempotency_keys": 1, "already_there": 0})
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
        "/v1/standards",
        "/v1/standards/STAND-1",
        "/v1/standards/STAND-1/affected",
        "/v1/customers",
        "/v1/sensors/PAPER-2005/item",
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
            paths.push(format!("/v1/calibrations/{cid}/signatures"));
        }
    }
    assert_eq!(paths.len(), 11 + 2 * 4 + 3 * 3);
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

/// A SQLite database holding `n` calibrations of a few sensors, made through
/// a server; returns its path.
async fn source_with(dir: &std::path::Path, n: usize) -> std::path::PathBuf {
    let db = dir.join("source.db");
    let s = Server::start_with(&db, &[], "info");
    let c = reqwest::Client::new();
    let paper: Value =
        serde_json::from_slice(&std::fs::read("examples/paper-table1.json").unwrap()).unwrap();
    let mut tasks = tokio::task::JoinSet::new();
    for lane in 0..8 {
        let (c, base, paper) = (c.clone(), s.base.clone(), paper.clone());
        tasks.spawn(async move {
            for k in (lane..n).step_by(8) {
                let mut body = paper.clone();
                body["sensor_id"] = json!(format!("MOVE-{}", k % 10));
                body["performed_at"] = json!(format!("2020-01-01T00:00:{:02}.{k:06}Z", k % 60));
                let r = call(
                    &c,
                    reqwest::Method::POST,
                    format!("{base}/v1/calibrations"),
                    Some(("application/json", body.to_string().into_bytes())),
                    None,
                )
                .await;
                assert_eq!(r.status(), StatusCode::CREATED);
            }
        });
    }
    while let Some(t) = tasks.join_next().await {
        t.unwrap();
    }
    s.terminate();
    let mut s = s;
    assert!(s.child.wait().unwrap().success());
    db
}

fn serve_refused(db: &str) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["serve", "--listen", "127.0.0.1:0", "--database", db])
        .env("ACCELCAL_ADMIN_TOKEN", ADMIN)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "the service must refuse to start"
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Hardening round three, finding 8: a migrate killed half-way leaves its
/// target marked — the service refuses to start on it, saying what to do —
/// and the same migrate run again resumes: it skips what is there, copies
/// the rest, and the result holds every calibration exactly once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_migrate_is_refused_by_the_service_and_resumed() {
    const N: usize = 1200;
    let dir = tempfile::tempdir().unwrap();
    let sqlite = source_with(dir.path(), N).await;
    let pg = accelcal_testkit::pg::TestDb::create().await;
    let from = format!("sqlite:{}", sqlite.display());
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["migrate", "--from", &from, "--to", &pg.url])
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let client = pg.client().await;
    let count = |sql: &'static str| {
        let client = &client;
        async move {
            client
                .query_one(sql, &[])
                .await
                .map_or(0, |r| r.get::<_, i64>(0))
        }
    };
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while count("SELECT count(*) FROM calibrations").await < 50 {
        assert!(
            std::time::Instant::now() < deadline,
            "the copy never started"
        );
        tokio::time::sleep(std::time::Duration::from_millis(5)).await;
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let partial = count("SELECT count(*) FROM calibrations").await;
    assert!(
        partial < N as i64,
        "the copy finished before it was killed ({partial})"
    );
    assert_eq!(count("SELECT count(*) FROM import_in_progress").await, 1);
    let err = serve_refused(&pg.url);
    assert!(err.contains("did not finish"), "{err}");
    assert!(err.contains("run the same migrate again"), "{err}");
    assert!(err.contains(&sqlite.display().to_string()), "{err}");

    let copied = migrated(&from, &pg.url);
    assert_eq!(
        copied["calibrations"].as_i64().unwrap() + copied["already_there"].as_i64().unwrap(),
        N as i64,
        "{copied}: every calibration exactly once"
    );
    assert_eq!(count("SELECT count(*) FROM calibrations").await, N as i64);
    assert_eq!(
        count("SELECT CAST(sum(calibration_count) AS bigint) FROM sensors").await,
        N as i64
    );
    assert_eq!(count("SELECT count(*) FROM import_in_progress").await, 0);
    let s = Server::start_with(&pg.url, &[], "info");
    let sensors = s.get_json("/v1/sensors").await;
    assert_eq!(sensors["items"].as_array().unwrap().len(), 10);
}

/// Finding 8: `--into-non-empty` never replaces what the target holds: a
/// sensor type of the same id with other content stops the copy, naming it,
/// and leaves the target's type as it was (and the target marked until a
/// re-run finishes).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_migrate_never_overwrites_the_targets_rows() {
    let dir = tempfile::tempdir().unwrap();
    let sqlite = dir.path().join("types.db");
    let target = dir.path().join("target.db");
    let c = reqwest::Client::new();
    let nav: Value =
        serde_json::from_slice(&std::fs::read("examples/sensor-type-nav.json").unwrap()).unwrap();
    let mut lenient = nav.clone();
    lenient["interval_days"] = json!(3650);
    for (db, t) in [(&sqlite, &nav), (&target, &lenient)] {
        let s = Server::start_with(db, &[], "info");
        let r = call(
            &c,
            reqwest::Method::PUT,
            format!("{}/v1/sensor-types/NAV", s.base),
            Some(("application/json", t.to_string().into_bytes())),
            None,
        )
        .await;
        assert_eq!(r.status(), StatusCode::CREATED);
        s.terminate();
        let mut s = s;
        assert!(s.child.wait().unwrap().success());
    }
    let from = format!("sqlite:{}", sqlite.display());
    let to = target.display().to_string();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["migrate", "--from", &from, "--to", &to, "--into-non-empty"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("sensor type `NAV` with other content"),
        "{err}"
    );
    assert!(serve_refused(&to).contains("did not finish"));
    let conn = rusqlite::Connection::open(&target).unwrap();
    let interval: i64 = conn
        .query_row(
            "SELECT json_extract(definition, '$.interval_days') FROM sensor_types WHERE type_id = 'NAV'",
            [],
            |r| r.get(0),
        )
        .unwrap();
    assert_eq!(interval, 3650, "the target's type is untouched");
}
