//! Each engine's own promises: its schema refuses non-finite numbers and
//! changes, commits are durable, TLS follows the URL, leases of a crashed
//! process are freed, the pool is reused.

use super::*;
use accelcal::domain::review::Basis;

/// Many reads at once share the pool's reader connections: none is opened
/// beyond them (an open parses the whole schema; churning connections under
/// load was the submit path's largest cost after the disk).
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn sqlite_concurrent_reads_reuse_the_pool() {
    let dir = tempfile::tempdir().unwrap();
    let store = Arc::new(SqliteStore::open(dir.path().join("readers.db")).unwrap());
    store
        .insert_calibration(calibration("R-1", "2026-01-01T00:00:00Z"), None)
        .await
        .unwrap();
    let before = store.connections_opened();
    for _ in 0..4 {
        let reads: Vec<_> = (0..64)
            .map(|_| {
                let store = store.clone();
                tokio::spawn(async move {
                    store
                        .previous_calibration(
                            "R-1".into(),
                            t("2026-06-01T00:00:00Z"),
                            Basis::NotRejected,
                        )
                        .await
                })
            })
            .collect();
        for r in reads {
            assert!(r.await.unwrap().unwrap().is_some());
        }
    }
    let opened = store.connections_opened();
    assert!(
        opened <= accelcal::store::sqlite::READERS + 1,
        "{opened} connections opened for 256 reads ({before} before them)"
    );
}

/// Every pooled connection commits durably, whatever the server's default.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_every_connection_commits_durably() {
    let db = pg::TestDb::create().await;
    db.client()
        .await
        .batch_execute(&format!(
            "ALTER DATABASE {} SET synchronous_commit = off",
            db.name
        ))
        .await
        .unwrap();
    let store = Arc::new(PostgresStore::open(&db.url).await.unwrap());
    let checks: Vec<_> = (0..32)
        .map(|_| {
            let s = store.clone();
            tokio::spawn(async move { s.session_setting("synchronous_commit").await.unwrap() })
        })
        .collect();
    for c in checks {
        assert_eq!(c.await.unwrap(), "on");
    }
    assert_eq!(
        store.session_setting("application_name").await.unwrap(),
        "accelcal"
    );
}

/// TLS as the URL asks: `sslmode=require` encrypts (the test server has
/// TLS on), `disable` does not, and a certificate that does not chain to
/// the given `sslrootcert` is refused.
#[tokio::test]
async fn postgres_tls_follows_the_url() {
    let db = pg::TestDb::create().await;
    let with = |params: &str| {
        let sep = if db.url.contains('?') { '&' } else { '?' };
        format!("{}{sep}{params}", db.url)
    };
    let required = PostgresStore::open(&with("sslmode=require")).await.unwrap();
    assert!(
        required.encrypted().await.unwrap(),
        "sslmode=require must encrypt"
    );
    let plain = PostgresStore::open(&with("sslmode=disable")).await.unwrap();
    assert!(!plain.encrypted().await.unwrap());
    // A CA that signed nothing here: the server's certificate cannot chain to it.
    let dir = tempfile::tempdir().unwrap();
    let ca = dir.path().join("other-ca.pem");
    std::fs::write(&ca, OTHER_CA).unwrap();
    let refused = PostgresStore::open(&with(&format!(
        "sslmode=require&sslrootcert={}",
        ca.display()
    )))
    .await;
    let Err(StoreError::Unavailable(why)) = refused else {
        panic!("an unverifiable server must be refused");
    };
    let why = format!("{why:?}");
    assert!(
        why.contains("UnknownIssuer"),
        "refused for its certificate: {why}"
    );
}

/// A triad's elements as stored, and three forms each schema refuses: a
/// `null` (a NaN as serde_json writes it) inside `S`, text inside `b`, and
/// no `T`.
const TRIAD: &str = r#"{"method":"known_orientations","b":[0.1,0.2,0.3],"b_std_errors":null,
    "S":[[1,0,0],[0,1,0],[0,0,1]],"S_std_errors":[[1e-4,0,0],[0,1e-4,0],[0,0,1e-4]],
    "T":[[1,0,0],[0,1,0],[0,0,1]],"T_std_errors":null}"#;
const TRIAD_NULL_IN_S: &str = r#"{"method":"known_orientations","b":[0.1,0.2,0.3],
    "S":[[1,0,0],[0,null,0],[0,0,1]],"T":[[1,0,0],[0,1,0],[0,0,1]]}"#;
const TRIAD_TEXT_IN_B: &str = r#"{"method":"known_orientations","b":[0.1,"0.2",0.3],
    "S":[[1,0,0],[0,1,0],[0,0,1]],"T":[[1,0,0],[0,1,0],[0,0,1]]}"#;
const TRIAD_WITHOUT_T: &str = r#"{"method":"known_orientations","b":[0.1,0.2,0.3],
    "S":[[1,0,0],[0,1,0],[0,0,1]]}"#;

/// A self-signed CA certificate that signed nothing the test server holds.
const OTHER_CA: &str = include_str!("other-ca.pem");

/// The PostgreSQL schema itself refuses a non-finite (`null`) number and
/// any change to a stored calibration.
#[tokio::test]
async fn postgres_schema_refuses_non_finite_numbers_and_changes() {
    let db = pg::TestDb::create().await;
    let store = PostgresStore::open(&db.url).await.unwrap();
    let c = calibration("S-1", "2026-01-01T00:00:00Z");
    store.insert_calibration(c.clone(), None).await.unwrap();
    let client = db.client().await;
    let copy = |coefficients: &'static str, expanded: &'static str| {
        let client = &client;
        let id = c.id;
        async move {
            client
                .execute(
                    "INSERT INTO calibrations SELECT $1, sensor_id, station_id, performed_at, received_at, \
                     unit, model, runs, $2::text::json, std_errors, $3::text::json, result, submission, \
                     content_type, submitted_by, sensor_type, verdict, due_at FROM calibrations WHERE id = $4",
                    &[&Uuid::now_v7(), &coefficients, &expanded, &id],
                )
                .await
        }
    };
    let good = r#"{"k0":1e-6,"ki":2e-6}"#;
    let refused = copy(r#"{"k0":null,"ki":-1.2}"#, good).await.unwrap_err();
    assert!(format!("{refused:?}").contains("finite"), "{refused:?}");
    assert!(copy(r#"{"k0":"1","ki":-1.2}"#, good).await.is_err());
    let refused = copy(r#"{"k0":0.5,"ki":-1.2}"#, r#"{"k0":null}"#)
        .await
        .unwrap_err();
    assert!(
        format!("{refused:?}").contains("expanded uncertainties"),
        "{refused:?}"
    );
    copy(r#"{"k0":0.5,"ki":-1.2}"#, good).await.unwrap();
    let triad = |elements: &'static str| {
        let client = &client;
        let id = c.id;
        async move {
            client
                .execute(
                    "INSERT INTO calibrations (id, sensor_id, performed_at, received_at, unit, \
                     model, runs, coefficients, std_errors, result, submission, content_type, \
                     submitted_by, triad) SELECT $1, sensor_id, performed_at, received_at, unit, \
                     model, runs, '{}', '{}', result, submission, content_type, submitted_by, \
                     $2::text::json FROM calibrations WHERE id = $3",
                    &[&Uuid::now_v7(), &elements, &id],
                )
                .await
        }
    };
    for refused in [TRIAD_NULL_IN_S, TRIAD_TEXT_IN_B, TRIAD_WITHOUT_T] {
        let e = triad(refused).await.unwrap_err();
        assert!(format!("{e:?}").contains("triad"), "{refused}: {e:?}");
    }
    triad(TRIAD).await.unwrap();
    let changed = client
        .execute("UPDATE calibrations SET unit = 'x' WHERE id = $1", &[&c.id])
        .await
        .unwrap_err();
    assert!(
        format!("{changed:?}").contains("never changes"),
        "{changed:?}"
    );
}

#[tokio::test]
async fn sqlite_frees_leases_of_a_crashed_process_at_open() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("leases.db");
    let now = Timestamp::now();
    let first = SqliteStore::open(&path).unwrap();
    assert_eq!(
        first
            .claim_key(key("k", 1), now, now.plus_seconds(3600))
            .await
            .unwrap(),
        Claim::Fresh
    );
    drop(first);
    let second = SqliteStore::open(&path).unwrap();
    assert_eq!(
        second
            .claim_key(key("k", 1), now, now.plus_seconds(3600))
            .await
            .unwrap(),
        Claim::Fresh
    );
}

/// The SQLite schema itself refuses what the service would never write: a
/// non-finite (`null`) coefficient, and any change to a stored calibration.
#[tokio::test]
async fn sqlite_schema_refuses_non_finite_numbers_and_changes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("schema.db");
    let store = SqliteStore::open(&path).unwrap();
    let c = calibration("S-1", "2026-01-01T00:00:00Z");
    store.insert_calibration(c.clone(), None).await.unwrap();
    store.close().await;
    let db = rusqlite::Connection::open(&path).unwrap();
    let copy_with = |coefficients: &str, expanded: &str| {
        db.execute(
            "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, \
             unit, model, runs, coefficients, std_errors, result, submission, content_type, \
             submitted_by, sensor_type, verdict, due_at, expanded) \
             SELECT ?1, sensor_id, station_id, performed_at, received_at, \
             unit, model, runs, ?2, std_errors, result, submission, content_type, submitted_by, \
             sensor_type, verdict, due_at, ?3 FROM calibrations WHERE id = ?4",
            rusqlite::params![
                Uuid::now_v7().to_string(),
                coefficients,
                expanded,
                c.id.to_string()
            ],
        )
    };
    let good = r#"{"k0":1e-6,"ki":2e-6}"#;
    let copy = |coefficients: &str| copy_with(coefficients, good);
    let refused = copy(r#"{"k0":null,"ki":-1.2}"#).unwrap_err().to_string();
    assert!(refused.contains("finite"), "{refused}");
    assert!(copy(r#"{"k0":"1","ki":-1.2}"#).is_err());
    let refused = copy_with(r#"{"k0":0.5,"ki":-1.2}"#, r#"{"k0":null,"ki":1e-6}"#)
        .unwrap_err()
        .to_string();
    assert!(
        refused.contains("expanded uncertainties must be finite"),
        "{refused}"
    );
    copy(r#"{"k0":0.5,"ki":-1.2}"#).unwrap();
    let triad = |elements: &str| {
        db.execute(
            "INSERT INTO calibrations (id, sensor_id, performed_at, received_at, unit, model, \
             runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
             triad) SELECT ?1, sensor_id, performed_at, received_at, unit, model, runs, '{}', \
             '{}', result, submission, content_type, submitted_by, ?2 FROM calibrations \
             WHERE id = ?3",
            rusqlite::params![Uuid::now_v7().to_string(), elements, c.id.to_string()],
        )
    };
    for refused in [TRIAD_NULL_IN_S, TRIAD_TEXT_IN_B, TRIAD_WITHOUT_T] {
        let e = triad(refused).unwrap_err().to_string();
        assert!(
            e.contains("triad's elements must be finite"),
            "{refused}: {e}"
        );
    }
    triad(TRIAD).unwrap();
    let changed = db
        .execute(
            "UPDATE calibrations SET coefficients = '{}' WHERE id = ?1",
            [c.id.to_string()],
        )
        .unwrap_err()
        .to_string();
    assert!(changed.contains("never changes"), "{changed}");
}
