//! `accelcal audit verify` sees what is served (issue 42 item 4): a database
//! populated through the service — a typed calibration made with standards,
//! approved (its certificate issued), a standard found nonconforming and
//! the calibration held, customers, items, tokens — verifies; then, on a copy
//! of it each, one protected table is tampered with behind the service's
//! back with `sqlite3` or `psql` (its triggers dropped first, and put back
//! after), and `verify` names the row and exits 1. A row with no entry is
//! reported, and `accelcal audit adopt` adopts only those.

use std::process::Command;

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::process::binary;
use accelcal_testkit::*;

/// What the populated database holds, by id.
struct Populated {
    approved: String,
    submitted: String,
    reviewer_token: String,
    nonconformity: String,
    sensor: String,
}

async fn populate(app: &TestApp) -> Populated {
    let put = async |path: &str, body: Value| {
        let res = app.put(path, ADMIN, &body).await;
        assert!(
            res.status().is_success(),
            "{path}: {}",
            res.text().await.unwrap()
        );
    };
    put(
        "/v1/standards/DH-1",
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap(),
    )
    .await;
    put(
        "/v1/customers/ACME",
        json!({"name": "Acme Navigation GmbH", "address": "1 Gyro Way", "due_date_agreed": true}),
    )
    .await;
    put(
        "/v1/sensors/VER-1/item",
        json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": "QA-1", "customer": "ACME"}),
    )
    .await;
    put(
        "/v1/sensor-types/NAV",
        json!({"unit": "mA", "limits": {"k0": {"min": -0.01, "max": 0.01}}, "decision_rule": "simple"}),
    )
    .await;
    let res = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "reviewer", "holder": "Rita"}),
        )
        .await;
    let token: Value = res.json().await.unwrap();
    let rita = token["token"].as_str().unwrap().to_owned();
    let mut body = submission("VER-1", "2026-06-01T00:00:00Z", 4);
    body["sensor_type"] = json!("NAV");
    body["standards"] = json!({"stand": "DH-1"});
    let approved = app.submit(ADMIN, &body).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let res = app
        .post(
            &format!("/v1/calibrations/{approved}/review"),
            &rita,
            &json!({"decision": "approve"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let submitted = app
        .submit(ADMIN, &submission("VER-2", "2026-07-01T00:00:00Z", 4))
        .await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let res = app
        .post(
            "/v1/standards/DH-1/nonconformity",
            ADMIN,
            &json!({"found_at": "2026-06-15T00:00:00Z", "reason": "Indexing error."}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let nc: Value = res.json().await.unwrap();
    Populated {
        approved,
        submitted,
        reviewer_token: token["id"].as_str().unwrap().to_owned(),
        nonconformity: nc["nonconformity"]["id"].as_str().unwrap().to_owned(),
        sensor: "VER-1".into(),
    }
}

/// One engine's command-line client against one database.
struct Sql {
    engine: Engine,
    url: String,
}

impl Sql {
    fn run(&self, sql: &str) -> String {
        let out = match self.engine {
            Sqlite => Command::new("sqlite3").arg(&self.url).arg(sql).output(),
            Postgres => Command::new("psql")
                .args([&self.url, "-v", "ON_ERROR_STOP=1", "-At", "-c", sql])
                .output(),
        }
        .expect("sqlite3 and psql are installed (.ci/run)");
        assert!(
            out.status.success(),
            "{sql}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).trim().to_owned()
    }

    /// Runs `sql` with the triggers of `table` dropped, and puts them back.
    fn behind_the_back(&self, table: &str, sql: &str) {
        let saved: Vec<String> = match self.engine {
            Sqlite => {
                let names = self.run(&format!(
                    "SELECT name FROM sqlite_master WHERE type = 'trigger' AND tbl_name = '{table}'"
                ));
                names
                    .lines()
                    .filter(|n| !n.is_empty())
                    .map(|n| {
                        let def = self.run(&format!(
                            "SELECT sql FROM sqlite_master WHERE type = 'trigger' AND name = '{n}'"
                        ));
                        self.run(&format!("DROP TRIGGER {n}"));
                        format!("{def};")
                    })
                    .collect()
            }
            Postgres => {
                let names = self.run(&format!(
                    "SELECT t.tgname FROM pg_trigger t JOIN pg_class c ON c.oid = t.tgrelid \
                     WHERE c.relname = '{table}' AND NOT t.tgisinternal"
                ));
                names
                    .lines()
                    .filter(|n| !n.is_empty())
                    .map(|n| {
                        let def = self.run(&format!(
                            "SELECT pg_get_triggerdef(t.oid) FROM pg_trigger t JOIN pg_class c \
                             ON c.oid = t.tgrelid WHERE c.relname = '{table}' AND t.tgname = '{n}'"
                        ));
                        self.run(&format!("DROP TRIGGER {n} ON {table}"));
                        def
                    })
                    .collect()
            }
        };
        self.run(sql);
        for def in saved {
            self.run(&def);
        }
    }
}

/// `accelcal audit verify` on `url`: whether it passed, and what it said.
fn verify(url: &str) -> (bool, String) {
    let out = Command::new(binary())
        .args(["audit", "verify", "--database", url])
        .output()
        .unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), said)
}

/// A copy of the database at `url` (an engine's own copy: `.backup`, a
/// template), removed when the copy is dropped.
struct Copy {
    url: String,
    _dir: Option<tempfile::TempDir>,
    pg_name: Option<String>,
}

impl Copy {
    fn of(engine: Engine, url: &str) -> Copy {
        match engine {
            Sqlite => {
                let dir = tempfile::tempdir().unwrap();
                let to = dir.path().join("copy.db").to_str().unwrap().to_owned();
                Sql {
                    engine,
                    url: url.to_owned(),
                }
                .run(&format!(".backup '{to}'"));
                Copy {
                    url: to,
                    _dir: Some(dir),
                    pg_name: None,
                }
            }
            Postgres => {
                let from = url.rsplit_once('/').unwrap().1.to_owned();
                let name = format!("accelcal_t_{}", uuid::Uuid::now_v7().simple());
                let admin = Sql {
                    engine,
                    url: pg::admin_url(),
                };
                admin.run(&format!(
                    "SELECT pg_terminate_backend(pid) FROM pg_stat_activity \
                     WHERE datname = '{from}' AND pid <> pg_backend_pid()"
                ));
                admin.run(&format!("CREATE DATABASE {name} TEMPLATE {from}"));
                Copy {
                    url: pg::with_database(&pg::admin_url(), &name),
                    _dir: None,
                    pg_name: Some(name),
                }
            }
        }
    }
}

impl Drop for Copy {
    fn drop(&mut self) {
        if let Some(name) = &self.pg_name {
            let _ = Command::new("psql")
                .args([
                    &pg::admin_url(),
                    "-c",
                    &format!("DROP DATABASE {name} WITH (FORCE)"),
                ])
                .output();
        }
    }
}

#[rstest]
#[tokio::test]
async fn verify_finds_every_protected_row_tampered_with(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let mut app = TestApp::configured(engine, |c| {
        c.web.laboratory.name = Some("Inertial Test Lab".into());
        c.web.laboratory.country = Some("CH".into());
    })
    .await;
    let p = populate(&app).await;
    app.stop().await;
    let db = app.take_database().unwrap();
    // Straight to the server (the test's relay would wait on this thread).
    let url = match engine {
        Sqlite => db.url.clone(),
        Postgres => pg::with_database(&pg::admin_url(), db.url.rsplit_once('/').unwrap().1),
    };
    // As the service left it, and on the engine's own copy: intact.
    let (ok, said) = verify(&url);
    assert!(ok, "{said}");
    for table in [
        "calibrations",
        "signatures",
        "certificates",
        "standards",
        "tokens",
        "nonconformities",
        "sensors",
    ] {
        assert!(
            said.contains(&format!("\"{table}\"")),
            "{table} checked: {said}"
        );
    }
    let (ok, said) = verify(&Copy::of(engine, &url).url);
    assert!(ok, "{said}");

    let pg = engine == Postgres;
    let json_set = |column: &str, path: &str, value: &str| {
        if pg {
            format!(
                "jsonb_set({column}::jsonb, '{{{}}}', '{value}')::json",
                path.replace('.', ",")
            )
        } else {
            format!("json_set({column}, '$.{path}', json('{value}'))")
        }
    };
    let (a, s) = (&p.approved, &p.submitted);
    let at = if pg {
        "'2026-11-27T00:00:00Z'"
    } else {
        "'2026-11-27T00:00:00.000000Z'"
    };
    // (table, tampering, what verify names)
    let cases: Vec<(&str, String, String)> = vec![
        (
            "calibrations",
            format!(
                "UPDATE calibrations SET coefficients = {} WHERE id = '{a}'",
                json_set("coefficients", "ki", "-1.3")
            ),
            format!("calibrations/{a}"),
        ),
        (
            "signatures",
            format!(
                "INSERT INTO signatures (calibration_id, seq, action, state, meaning, token_id, role, \
                 holder, signed_at, comment, superseded_by) VALUES ('{s}', 1, 'approve', 'approved', \
                 'Approved', 'forger', 'reviewer', NULL, {at}, NULL, NULL)"
            ),
            format!("calibrations/{s}/signatures/1"),
        ),
        (
            "signatures",
            format!(
                "UPDATE signatures SET comment = 'looks fine' WHERE calibration_id = '{a}' AND seq = 1"
            ),
            format!("calibrations/{a}/signatures/1"),
        ),
        (
            "certificates",
            format!(
                "UPDATE certificates SET html = replace(html, 'QA-1', 'QA-9') WHERE calibration_id = '{a}'"
            ),
            format!("calibrations/{a}/certificate/1"),
        ),
        (
            "standards",
            format!(
                "UPDATE standards SET definition = {} WHERE standard_id = 'DH-1'",
                json_set("definition", "angle_std_arcsec", "0.1")
            ),
            "standards/DH-1".into(),
        ),
        (
            "customers",
            format!(
                "UPDATE customers SET definition = {} WHERE customer_id = 'ACME'",
                json_set("definition", "name", "\"Mallory Ltd\"")
            ),
            "customers/ACME".into(),
        ),
        (
            "items",
            format!(
                "UPDATE items SET definition = {} WHERE sensor_id = 'VER-1'",
                json_set("definition", "serial", "\"QA-2\"")
            ),
            "items/VER-1".into(),
        ),
        (
            "sensor_types",
            format!(
                "UPDATE sensor_types SET definition = {} WHERE type_id = 'NAV'",
                json_set("definition", "interval_days", "3650")
            ),
            "sensor-types/NAV".into(),
        ),
        (
            "tokens",
            format!(
                "UPDATE tokens SET role = 'admin' WHERE id = '{}'",
                p.reviewer_token
            ),
            format!("tokens/{}", p.reviewer_token),
        ),
        (
            "nonconformities",
            format!(
                "UPDATE nonconformities SET reason = 'nothing' WHERE id = '{}'",
                p.nonconformity
            ),
            format!("nonconformities/{}", p.nonconformity),
        ),
        (
            "nonconformity_calibrations",
            format!(
                "DELETE FROM nonconformity_calibrations WHERE nonconformity_id = '{}'",
                p.nonconformity
            ),
            format!("nonconformities/{}", p.nonconformity),
        ),
        (
            "sensors",
            format!(
                "UPDATE sensors SET latest_verdict = 'pass', calibration_count = 7 WHERE sensor_id = '{}'",
                p.sensor
            ),
            format!("sensors/{}", p.sensor),
        ),
        (
            "customers",
            format!(
                "INSERT INTO customers (customer_id, definition, updated_at) SELECT 'FORGED', \
                 {}, updated_at FROM customers WHERE customer_id = 'ACME'",
                json_set("definition", "customer_id", "\"FORGED\"")
            ),
            "customers/FORGED".into(),
        ),
        (
            "items",
            "DELETE FROM items WHERE sensor_id = 'VER-1'".into(),
            "items/VER-1".into(),
        ),
    ];
    for (table, sql, object) in cases {
        let copy = Copy::of(engine, &url);
        let on = Sql {
            engine,
            url: copy.url.clone(),
        };
        on.behind_the_back(table, &sql);
        let (ok, said) = verify(&copy.url);
        assert!(!ok, "{table}: {sql} went unnoticed: {said}");
        assert!(
            said.contains(&object),
            "{table}: {object} not named: {said}"
        );
    }

    // A row with no entry at all is reported as such; adopt records it —
    // and only such rows: an edit is never adopted.
    let adopt = |url: &str| {
        Command::new(binary())
            .args(["audit", "adopt", "--database", url])
            .output()
            .unwrap()
    };
    // An entry deleted breaks the chain: nothing is adopted.
    let copy = Copy::of(engine, &url);
    let on = Sql {
        engine,
        url: copy.url.clone(),
    };
    on.behind_the_back("audit", "DELETE FROM audit WHERE seq = 3");
    let (ok, said) = verify(&copy.url);
    assert!(!ok && said.contains("audit entry 3"), "{said}");
    assert!(!adopt(&copy.url).status.success());
    drop(copy);
    let copy = Copy::of(engine, &url);
    let on = Sql {
        engine,
        url: copy.url.clone(),
    };
    on.behind_the_back(
        "customers",
        &format!(
            "INSERT INTO customers (customer_id, definition, updated_at) SELECT 'OLD', {}, \
             updated_at FROM customers WHERE customer_id = 'ACME'",
            json_set("definition", "customer_id", "\"OLD\"")
        ),
    );
    let (ok, said) = verify(&copy.url);
    assert!(
        !ok && said.contains("customers/OLD") && said.contains("no audit entry"),
        "{said}"
    );
    let out = adopt(&copy.url);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["objects"], json!(["customers/OLD"]));
    let (ok, said) = verify(&copy.url);
    assert!(ok, "{said}");
    // Adopted, then edited: found.
    on.run(&format!(
        "UPDATE customers SET definition = {} WHERE customer_id = 'OLD'",
        json_set("definition", "name", "\"Changed\"")
    ));
    let (ok, said) = verify(&copy.url);
    assert!(!ok && said.contains("customers/OLD"), "{said}");
    // An edit is not adopted.
    let out = adopt(&copy.url);
    assert!(!out.status.success());
}
