//! The command line's promises, run as a user runs them: `identify`,
//! `token create`, `health`, `serve`'s admin-token rules and first start.
//! (`submit` is exercised by the walkthrough and `tests/api/client.rs`.)

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use serde_json::Value;

use accelcal_testkit::process::Server;

fn accelcal() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_accelcal"));
    c.env_remove("ACCELCAL_ADMIN_TOKEN")
        .env_remove("ACCELCAL_DATABASE_URL")
        .env_remove("ACCELCAL_URL")
        .env_remove("ACCELCAL_TOKEN");
    c
}

/// Asserts a command succeeded, showing what it said when it did not.
fn succeeded(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn reference() -> Value {
    serde_json::from_str(include_str!("../../core/tests/data/reference.json")).unwrap()
}

#[test]
fn identify_prints_the_result_or_the_problem() {
    let out = accelcal()
        .args(["identify", "examples/paper-table1.json"])
        .output()
        .unwrap();
    succeeded(&out);
    let r: Value = serde_json::from_slice(&out.stdout).unwrap();
    let want = reference()["table1"]["fused"]["kp"].as_f64().unwrap();
    let got = r["fused"]["coefficients"]["kp"].as_f64().unwrap();
    assert!((got - want).abs() <= 1e-12 * want.abs(), "{got} vs {want}");
    assert!(
        r.get("id").is_none(),
        "nothing is stored, so there is no id"
    );

    // CSV by extension.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("paper.csv");
    std::fs::write(
        &csv,
        format!(
            "# sensor_id: CLI-CSV\n{}",
            include_str!("../../core/tests/data/table1.csv")
        ),
    )
    .unwrap();
    let out = accelcal().arg("identify").arg(&csv).output().unwrap();
    assert!(out.status.success());
    let r: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["sensor_id"], "CLI-CSV");

    // Bad input: the problem document on stderr, exit status 1.
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"sensor_id": "x", "batchs": 2}"#).unwrap();
    let out = accelcal().arg("identify").arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let p: Value = serde_json::from_slice(&out.stderr).unwrap();
    assert_eq!(p["status"], 422);
    assert_eq!(p["errors"][0]["pointer"], "/batchs");
    // A missing file: exit status 2 and a message.
    let out = accelcal()
        .args(["identify", "no/such/file.json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read"));
}

#[tokio::test]
async fn token_create_issues_a_token_the_server_accepts() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("tokens.db");
    let out = accelcal()
        .args([
            "token",
            "create",
            "--role",
            "station",
            "--station",
            "LAB-7",
            "--label",
            "bench 7",
            "--create",
        ])
        .arg("--database")
        .arg(&db)
        .output()
        .unwrap();
    succeeded(&out);
    let created: Value = serde_json::from_slice(&out.stdout).unwrap();
    let token = created["token"].as_str().unwrap().to_owned();
    assert_eq!(created["role"], "station");
    assert_eq!(created["station_id"], "LAB-7");

    // Refusals name the flag.
    for (args, says) in [
        (vec!["--role", "root"], "--role"),
        (
            vec!["--role", "reader", "--station", "LAB-7"],
            "--station only a station token",
        ),
        (
            vec!["--role", "station", "--station", "bad id"],
            "--station must start",
        ),
    ] {
        let out = accelcal()
            .args(["token", "create"])
            .args(&args)
            .arg("--database")
            .arg(&db)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }

    let server = Server::start(&db);
    let res = reqwest::Client::new()
        .get(format!("{}/v1/sensors", server.base))
        .bearer_auth(&token)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
}

#[test]
fn health_exits_0_when_ready_and_1_when_not() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path().join("health.db"));
    let ok = accelcal()
        .args(["health", "--url", &server.base])
        .output()
        .unwrap();
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    drop(server);
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let closed = format!("http://{}", listener.local_addr().unwrap());
    drop(listener);
    let down = accelcal()
        .args(["health", "--url", &closed])
        .output()
        .unwrap();
    assert_eq!(down.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&down.stderr).contains("no answer"));
}

/// Finding 9 of hardening round three: a guessable configured admin token
/// (the README's old example, sixteen `a`s) refuses the start and says how
/// to make a good one.
#[test]
fn a_weak_admin_token_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    for weak in [
        "change-me-to-something-long",
        "aaaaaaaaaaaaaaaa",
        "fifteen-chars-x",
    ] {
        let out = accelcal()
            .args(["serve", "--listen", "127.0.0.1:0"])
            .env("ACCELCAL_ADMIN_TOKEN", weak)
            .arg("--database")
            .arg(dir.path().join("weak.db"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{weak}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("too weak"), "{err}");
        assert!(err.contains("head -c 32 /dev/urandom | base64"), "{err}");
    }
}

/// Starts `serve` with no admin token configured; gives the token line it
/// printed on standard output, if any, once it listens.
fn first_start(db: &std::path::Path) -> (std::process::Child, String, Option<String>) {
    let mut child = accelcal()
        .args(["serve", "--listen", "127.0.0.1:0", "--log-format", "json"])
        .arg("--database")
        .arg(db)
        .env("RUST_LOG", "info")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let mut address = String::new();
    for line in stderr.lines().map_while(Result::ok) {
        let v: Value = serde_json::from_str(&line).unwrap_or_default();
        if v["message"] == "accelcal listening" {
            address = v["address"].as_str().unwrap().to_owned();
            break;
        }
    }
    assert!(!address.is_empty(), "the server did not start");
    // Printed before listening: whatever stdout holds now is all there is.
    child.kill().unwrap();
    child.wait().unwrap();
    let mut printed = String::new();
    std::io::Read::read_to_string(&mut child.stdout.take().unwrap(), &mut printed).unwrap();
    let token = printed
        .lines()
        .find(|l| l.starts_with("acc_"))
        .map(str::to_owned);
    (child, address, token)
}

#[tokio::test]
async fn the_first_start_prints_an_admin_token_once() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("first.db");
    let (_, _, token) = first_start(&db);
    let token = token.expect("the first start prints an admin token");
    let (_, _, again) = first_start(&db);
    assert_eq!(again, None, "a second start prints no token");
    // The printed token is an admin token.
    let server = Server::start(&db);
    let res = reqwest::Client::new()
        .get(format!("{}/v1/tokens", server.base))
        .bearer_auth(&token)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    let tokens: Value = res.json().await.unwrap();
    assert_eq!(
        tokens["items"][0]["label"],
        "first admin (created at start)"
    );
}

/// Issue 31: `submit` to an address nothing listens on fails at once — one
/// line naming the URL, the refusal and what to do — instead of retrying.
#[test]
fn submit_to_nothing_fails_fast_and_says_why() {
    let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", probe.local_addr().unwrap());
    drop(probe);
    let start = std::time::Instant::now();
    let out = accelcal()
        .args([
            "submit",
            "examples/paper-table1.json",
            "--token",
            "x",
            "--url",
            &url,
        ])
        .output()
        .unwrap();
    assert!(start.elapsed() < std::time::Duration::from_secs(2));
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    for says in [
        url.as_str(),
        "Connection refused",
        "accelcal serve",
        "--url",
    ] {
        assert!(err.contains(says), "{says}: {err}");
    }
}

/// Issue 31: a reader that goes away (`| head`) ends the command quietly.
#[test]
fn a_closed_pipe_ends_quietly() {
    use std::io::Read as _;
    let mut child = accelcal()
        .args(["identify", "examples/paper-table1.json"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 1];
    child.stdout.take().unwrap().read_exact(&mut first).unwrap();
    // The pipe's reading end is closed here, before the output is whole.
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Issue 31: `token create` refuses a database file that does not exist
/// (the wrong directory) unless told to create it, and creates nothing.
#[test]
fn token_create_needs_an_existing_database_or_create() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("absent.db");
    let out = accelcal()
        .args(["token", "create", "--role", "station", "--database"])
        .arg(&db)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no database at") && err.contains("--create"),
        "{err}"
    );
    assert!(!db.exists());
    let out = accelcal()
        .args([
            "token",
            "create",
            "--role",
            "station",
            "--create",
            "--database",
        ])
        .arg(&db)
        .output()
        .unwrap();
    succeeded(&out);
    assert!(db.exists());
}

/// Issue 31: the format of a file is decided by its content (a CSV named
/// `.txt`), or by `--format`.
#[test]
fn the_format_comes_from_the_content() {
    let dir = tempfile::tempdir().unwrap();
    let txt = dir.path().join("table1.txt");
    std::fs::write(
        &txt,
        format!(
            "# sensor_id: TXT-1\n{}",
            std::fs::read_to_string("core/tests/data/table1.csv").unwrap()
        ),
    )
    .unwrap();
    let out = accelcal().arg("identify").arg(&txt).output().unwrap();
    succeeded(&out);
    let result: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(result["sensor_id"], "TXT-1");
    let forced = accelcal()
        .arg("identify")
        .arg(&txt)
        .args(["--format", "json"])
        .output()
        .unwrap();
    assert_eq!(
        forced.status.code(),
        Some(1),
        "read as JSON, it is not JSON"
    );
}

/// Issue 46 item 1: a DCC signing key or certificate that may not sign
/// refuses the start, naming the file at fault and why.
#[test]
fn a_signing_key_that_may_not_sign_refuses_the_start_naming_the_file() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let fixture = |name: &str| {
        let to = dir.path().join(name);
        std::fs::copy(format!("tests/data/signing/{name}"), &to).unwrap();
        std::fs::set_permissions(&to, std::fs::Permissions::from_mode(0o600)).unwrap();
        to
    };
    let (lab_key, lab_pem) = (fixture("lab.key"), fixture("lab.pem"));
    let (weak_key, weak_pem) = (fixture("weak.key"), fixture("weak.pem"));
    let (p384_key, p384_pem) = (fixture("p384.key"), fixture("p384.pem"));
    let pkcs1 = fixture("lab.pkcs1.key");
    let rotated_pem = fixture("rotated.pem");
    let (expired_key, expired_pem) = (fixture("expired.key"), fixture("expired.pem"));
    let open = dir.path().join("open.key");
    std::fs::copy(&lab_key, &open).unwrap();
    std::fs::set_permissions(&open, std::fs::Permissions::from_mode(0o644)).unwrap();
    let missing = dir.path().join("missing.pem");
    let cases = [
        (
            &weak_key,
            &weak_pem,
            "--dcc-signing-key",
            weak_key.clone(),
            "RSA key of 1024 bits",
        ),
        (
            &lab_key,
            &rotated_pem,
            "--dcc-signing-key",
            lab_key.clone(),
            "is not the key of the signing certificate",
        ),
        (
            &p384_key,
            &p384_pem,
            "--dcc-signing-key",
            p384_key.clone(),
            "ECDSA (1.3.132.0.34)",
        ),
        (
            &pkcs1,
            &lab_pem,
            "--dcc-signing-key",
            pkcs1.clone(),
            "openssl pkcs8 -topk8",
        ),
        (
            &open,
            &lab_pem,
            "--dcc-signing-key",
            open.clone(),
            "mode 644",
        ),
        (
            &expired_key,
            &expired_pem,
            "--dcc-signing-cert",
            expired_pem.clone(),
            "expired on 2021-01-01",
        ),
        (
            &lab_key,
            &missing,
            "--dcc-signing-cert",
            missing.clone(),
            "No such file",
        ),
        (
            &lab_key,
            &lab_key,
            "--dcc-signing-cert",
            lab_key.clone(),
            "X.509 certificate",
        ),
    ];
    for (key, cert, flag, file, why) in cases {
        let out = accelcal()
            .args(["serve", "--listen", "127.0.0.1:0", "--database"])
            .arg(dir.path().join("signing.db"))
            .arg("--dcc-signing-key")
            .arg(key)
            .arg("--dcc-signing-cert")
            .arg(cert)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{why}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&format!("{flag} {}", file.display())),
            "{why}: {err}"
        );
        assert!(err.contains(why), "{why}: {err}");
        assert!(
            !err.contains("PRIVATE KEY-----\nMII"),
            "the key must never be printed: {err}"
        );
    }
    // One flag without the other: the command line refuses it.
    let out = accelcal()
        .args(["serve", "--listen", "127.0.0.1:0", "--dcc-signing-key"])
        .arg(&lab_key)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--dcc-signing-cert"));
}
