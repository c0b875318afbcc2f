//! A SQLite file is one server's (hardening round three, findings 4 and
//! 10): a second server and the offline commands refuse a file being
//! served, naming it and the process; the WAL's index lives in the server's
//! heap, so a `-shm` file that cannot be written cannot kill it.

use std::process::Command;

use reqwest::StatusCode;
use serde_json::Value;

use accelcal_testkit::process::{ADMIN, Server};

fn accelcal() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_accelcal"));
    c.env_remove("ACCELCAL_ADMIN_TOKEN")
        .env_remove("ACCELCAL_DATABASE_URL");
    c
}

/// Finding 4: a second `serve` on a served file refuses to start, naming the
/// file and the other process; `token create` and `migrate --from` refuse
/// too, and wrote nothing.
#[tokio::test]
async fn a_served_file_is_refused_to_a_second_server_and_offline_commands() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("served.db");
    let server = Server::start(&db);
    let pid = server.child.id().to_string();
    let second = accelcal()
        .args(["serve", "--listen", "127.0.0.1:0", "--database"])
        .arg(&db)
        .output()
        .unwrap();
    assert_eq!(second.status.code(), Some(2));
    let err = String::from_utf8_lossy(&second.stderr);
    assert!(err.contains("served.db is in use by process"), "{err}");
    assert!(err.contains(&pid), "{err}");
    let token = accelcal()
        .args(["token", "create", "--role", "admin", "--database"])
        .arg(&db)
        .output()
        .unwrap();
    assert_ne!(token.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&token.stderr).contains("in use by process"));
    let copy = dir.path().join("copy.db");
    let migrate = accelcal()
        .args(["migrate", "--from"])
        .arg(&db)
        .arg("--to")
        .arg(&copy)
        .output()
        .unwrap();
    assert_ne!(migrate.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&migrate.stderr).contains("in use by process"));
    // The first server serves on, and no token was added behind its back.
    let tokens = server.get_json("/v1/tokens").await;
    assert_eq!(tokens["items"].as_array().unwrap().len(), 0, "{tokens}");
    // Once it has stopped, the offline command works.
    drop(server);
    let token = accelcal()
        .args(["token", "create", "--role", "admin", "--database"])
        .arg(&db)
        .output()
        .unwrap();
    assert_eq!(token.status.code(), Some(0), "{token:?}");
}

/// Clears the immutable flag it set, so the directory can be removed.
struct Immutable(std::path::PathBuf);

impl Drop for Immutable {
    fn drop(&mut self) {
        let _ = Command::new("chattr").arg("-i").arg(&self.0).status();
    }
}

/// Finding 10: with a `-shm` file beside the database that nobody may write
/// (`chattr +i`, as root), the server writes on — it keeps the WAL's index
/// in its own memory and never maps that file — and makes no `-shm` of
/// its own.
#[tokio::test]
async fn an_unwritable_shm_file_cannot_kill_the_server() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("shm.db");
    let shm = dir.path().join("shm.db-shm");
    std::fs::write(&shm, vec![0u8; 32 * 1024]).unwrap();
    let status = Command::new("chattr").arg("+i").arg(&shm).status().unwrap();
    assert!(
        status.success(),
        "chattr +i (needs root on ext4 or the like)"
    );
    let _guard = Immutable(shm.clone());
    let server = Server::start(&db);
    let client = reqwest::Client::new();
    let body: Value =
        serde_json::from_str(include_str!("../../examples/paper-table1.json")).unwrap();
    for _ in 0..20 {
        let res = client
            .post(format!("{}/v1/calibrations", server.base))
            .bearer_auth(ADMIN)
            .json(&body)
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), StatusCode::CREATED);
    }
    let sensor = server.get_json("/v1/sensors/PAPER-2005").await;
    assert_eq!(sensor["calibration_count"], 20);
    assert_eq!(
        std::fs::metadata(&shm).unwrap().len(),
        32 * 1024,
        "untouched"
    );
    drop(server);
    let fresh = tempfile::tempdir().unwrap();
    let other = Server::start(fresh.path().join("other.db"));
    drop(other);
    assert!(!fresh.path().join("other.db-shm").exists());
}
