//! The audit trail over HTTP and at the command line (issue 28 item 6):
//! `GET /v1/audit` for reviewers and admins, its filters and pages, and
//! `accelcal audit verify` on a database intact and tampered with.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

fn actions(page: &Value) -> Vec<(String, String)> {
    page["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["action"].as_str().unwrap().to_owned(),
                e["actor"]["holder"].as_str().unwrap_or("").to_owned(),
            )
        })
        .collect()
}

#[rstest]
#[tokio::test]
async fn the_trail_records_who_did_what(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let station = app.held_token("station", "Sam Station", Some("ST-1")).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let reader = app.token("reader", None).await;
    let mut body = submission("AU-1", "2026-01-01T00:00:00Z", 4);
    body["station_id"] = json!("ST-1");
    let id = app.submit(&station, &body).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/review"),
            &rita,
            &json!({"decision": "approve", "comment": "checked"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);

    let own = app
        .get_json(&format!("/v1/audit?object=calibrations/{id}"), &rita)
        .await;
    assert_eq!(
        actions(&own),
        [
            ("calibration.submitted".into(), "Sam Station".into()),
            ("calibration.approve".into(), "Rita Reviewer".into()),
        ]
    );
    let approve = &own["items"][1];
    assert_eq!(approve["actor"]["role"], "reviewer");
    assert_eq!(approve["change"]["from"], "submitted");
    assert_eq!(approve["change"]["to"], "approved");
    assert_eq!(approve["change"]["comment"], "checked");
    assert_eq!(approve["prev"], own["items"][0]["hash"]);
    assert_eq!(own["next"], Value::Null);

    // The whole trail, page by page, from the tokens the test created.
    let first = app.get_json("/v1/audit?limit=2", ADMIN).await;
    assert_eq!(first["items"].as_array().unwrap().len(), 2);
    assert_eq!(first["items"][0]["seq"], 1);
    let next = first["next"].as_str().unwrap();
    let second = app
        .get_json(&format!("/v1/audit?limit=2&after={next}"), ADMIN)
        .await;
    assert_eq!(second["items"][0]["seq"], 3);
    assert_eq!(second["items"][0]["prev"], first["items"][1]["hash"]);
    let tokens = app.get_json("/v1/audit?actor=env-admin", ADMIN).await;
    assert!(
        actions(&tokens)
            .iter()
            .filter(|(a, _)| a == "token.create")
            .count()
            >= 3,
        "{tokens}"
    );

    // Not for readers or stations.
    for token in [&reader, &station] {
        problem(app.get("/v1/audit", token).await, StatusCode::FORBIDDEN).await;
    }
    // A filter that names nothing finds nothing (control characters too).
    let none = app.get_json("/v1/audit?actor=%0C%C3%85", ADMIN).await;
    assert_eq!(none["items"], json!([]));
    // Bad parameters are named.
    for (query, param) in [
        ("limit=0", "limit"),
        ("after=-1", "after"),
        ("after=x", "after"),
        ("from=yesterday", "from"),
        ("object=", "object"),
        ("colour=red", "colour"),
    ] {
        let p = problem(
            app.get(&format!("/v1/audit?{query}"), ADMIN).await,
            StatusCode::BAD_REQUEST,
        )
        .await;
        assert!(
            p["detail"].as_str().unwrap().contains(param),
            "{query}: {p}"
        );
    }
}

/// `accelcal audit verify` on `database` passes; run off the runtime's
/// thread (a PostgreSQL test database's proxy runs on it).
pub(crate) async fn verifies(database: String) {
    let out = tokio::task::spawn_blocking(move || verify(&database))
        .await
        .unwrap();
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

pub(crate) fn verify(database: &str) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_accelcal"))
        .args(["audit", "verify", "--database", database])
        .output()
        .unwrap()
}

#[tokio::test]
async fn verify_names_the_first_entry_that_does_not_hold() {
    let mut app = TestApp::spawn(Sqlite).await;
    let id = app
        .submit(ADMIN, &submission("AU-2", "2026-01-01T00:00:00Z", 4))
        .await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    app.submit(ADMIN, &submission("AU-3", "2026-01-01T00:00:00Z", 4))
        .await;
    let path = app.db_path();
    app.stop().await;
    let database = path.to_str().unwrap();

    let out = verify(database);
    assert!(out.status.success(), "{out:?}");
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    // The service's configuration, then the two submissions.
    assert_eq!(
        (v["head_seq"].as_i64(), v["calibrations"].as_i64()),
        (Some(3), Some(2))
    );

    let db = rusqlite::Connection::open(&path).unwrap();
    db.execute_batch(&format!(
        "DROP TRIGGER calibrations_immutable; \
         UPDATE calibrations SET submission = x'00' WHERE id = '{id}'"
    ))
    .unwrap();
    drop(db);
    let out = verify(database);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.contains("audit entry 2:") && stderr.contains("submission is not the one recorded"),
        "{stderr}"
    );
}
