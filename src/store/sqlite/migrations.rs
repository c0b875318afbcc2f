//! Embedded migrations, applied in order; `PRAGMA user_version` counts those
//! applied. Every connection checks on open, and applies what is missing
//! under the write lock (so two connections never both migrate).
//!
//! Migrations run with foreign keys off, and the connection's setting is
//! restored after them: rebuilding a table that others reference (migration
//! 7) drops it first, which SQLite would otherwise refuse. Every reference
//! is checked (`PRAGMA foreign_key_check`) before the migrations commit, so
//! a migration that broke one is rolled back whole.

use rusqlite::{Connection, TransactionBehavior};

/// The migrations, oldest first.
const MIGRATIONS: &[&str] = &[
    include_str!("migrations/0001_init.sql"),
    include_str!("migrations/0002_idempotency.sql"),
    include_str!("migrations/0003_finite_and_immutable.sql"),
    include_str!("migrations/0004_metrology.sql"),
    include_str!("migrations/0005_sessions.sql"),
    include_str!("migrations/0006_lease_holders.sql"),
    include_str!("migrations/0007_large_columns_last.sql"),
    include_str!("migrations/0008_imports.sql"),
    include_str!("migrations/0009_token_holders.sql"),
    include_str!("migrations/0010_standards.sql"),
    include_str!("migrations/0011_signatures.sql"),
    include_str!("migrations/0012_customers.sql"),
    include_str!("migrations/0013_audit.sql"),
    include_str!("migrations/0014_nonconformities.sql"),
    include_str!("migrations/0015_triads.sql"),
    include_str!("migrations/0016_certificates.sql"),
    include_str!("migrations/0017_supersessions_indexed.sql"),
    include_str!("migrations/0018_webhooks.sql"),
    include_str!("migrations/0019_thermal.sql"),
];

/// Brings the database to the latest schema.
pub fn migrate(conn: &mut Connection) -> rusqlite::Result<()> {
    migrate_to(conn, MIGRATIONS.len())
}

/// Applies the first `latest` migrations (tests build older schemas).
fn migrate_to(conn: &mut Connection, latest: usize) -> rusqlite::Result<()> {
    let latest = latest as i64;
    let version: i64 = conn.pragma_query_value(None, "user_version", |r| r.get(0))?;
    if version >= latest {
        return Ok(());
    }
    // `PRAGMA foreign_keys` cannot change inside a transaction: off before
    // it, back as it was after it, whatever became of it.
    let keys: bool = conn.pragma_query_value(None, "foreign_keys", |r| r.get(0))?;
    conn.pragma_update(None, "foreign_keys", false)?;
    let out = apply(conn, latest);
    conn.pragma_update(None, "foreign_keys", keys)?;
    out
}

/// Applies the migrations from the database's version to `latest` in one
/// transaction, under the write lock.
fn apply(conn: &mut Connection, latest: i64) -> rusqlite::Result<()> {
    let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
    // Re-read under the write lock: another connection may have migrated.
    let version: i64 = tx.pragma_query_value(None, "user_version", |r| r.get(0))?;
    if version >= latest {
        return Ok(()); // nothing to apply, nothing to check
    }
    for sql in MIGRATIONS
        .iter()
        .take(latest as usize)
        .skip(version.max(0) as usize)
    {
        tx.execute_batch(sql)?;
    }
    let broken: Option<String> = tx
        .prepare("PRAGMA foreign_key_check")?
        .query_map([], |r| r.get::<_, String>(0))?
        .next()
        .transpose()?;
    if let Some(table) = broken {
        return Err(rusqlite::Error::SqliteFailure(
            rusqlite::ffi::Error::new(rusqlite::ffi::SQLITE_CONSTRAINT_FOREIGNKEY),
            Some(format!(
                "a migration left a broken reference in table {table}"
            )),
        ));
    }
    tx.pragma_update(None, "user_version", latest)?;
    tx.commit()
}

#[cfg(test)]
mod tests {
    use rusqlite::{Connection, params};

    use super::{MIGRATIONS, apply, migrate, migrate_to};

    /// A database at schema version 6 holding one calibration, its sensor
    /// and a completed idempotency key, written in version 6's column order.
    fn version_6() -> Connection {
        let mut c = Connection::open_in_memory().unwrap();
        migrate_to(&mut c, 6).unwrap();
        c.execute(
            "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, \
             model, runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
             sensor_type, verdict, due_at, expanded) VALUES ('c1', 'S-1', 'ST', \
             '2024-01-01T00:00:00.000000Z', '2024-01-02T00:00:00.000000Z', 'mA', '[\"k0\",\"ki\"]', 6, \
             '{\"k0\":1.5,\"ki\":2.0}', '{\"k0\":0.1,\"ki\":0.2}', '{\"the\":\"result\"}', x'7b7d', \
             'application/json', 'env-admin', NULL, 'pass', '2025-01-01T00:00:00.000000Z', \
             '{\"k0\":0.3}')",
            [],
        )
        .unwrap();
        c.execute(
            "INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
             latest_performed_at, latest_calibration_id, latest_verdict) \
             VALUES ('S-1', 1, '2024-01-01T00:00:00.000000Z', '2024-01-01T00:00:00.000000Z', 'c1', 'pass')",
            [],
        )
        .unwrap();
        c.execute(
            "INSERT INTO idempotency_keys (principal, key, request_hash, calibration_id, created_at) \
             VALUES ('env-admin', 'k', x'00', 'c1', '2024-01-02T00:00:00.000000Z')",
            [],
        )
        .unwrap();
        c
    }

    fn version(c: &Connection) -> i64 {
        c.pragma_query_value(None, "user_version", |r| r.get(0))
            .unwrap()
    }

    #[test]
    fn migration_7_keeps_every_value_and_puts_the_large_columns_last() {
        let mut c = version_6();
        migrate(&mut c).unwrap();
        assert_eq!(version(&c), MIGRATIONS.len() as i64);
        let columns: Vec<String> = c
            .prepare("SELECT name FROM pragma_table_info('calibrations') ORDER BY cid")
            .unwrap()
            .query_map([], |r| r.get(0))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        // A temperature model (version 19) is added after the large
        // columns: NULL in every other row, which a read of the row's header
        // answers without touching them; only a model's own row reads past
        // them (its migration says so).
        assert_eq!(columns.len(), 20, "{columns:?}");
        assert_eq!(columns[16..], ["triad", "result", "submission", "thermal"]);
        let row: (String, String, String, String, Vec<u8>, Option<String>, String) = c
            .query_row(
                "SELECT sensor_id, coefficients, verdict, result, submission, sensor_type, expanded \
                 FROM calibrations WHERE id = 'c1'",
                [],
                |r| {
                    Ok((
                        r.get(0)?,
                        r.get(1)?,
                        r.get(2)?,
                        r.get(3)?,
                        r.get(4)?,
                        r.get(5)?,
                        r.get(6)?,
                    ))
                },
            )
            .unwrap();
        assert_eq!(
            row,
            (
                "S-1".into(),
                "{\"k0\":1.5,\"ki\":2.0}".into(),
                "pass".into(),
                "{\"the\":\"result\"}".into(),
                b"{}".to_vec(),
                None,
                "{\"k0\":0.3}".into()
            )
        );
    }

    #[test]
    fn migration_7_leaves_one_index_per_sensor_and_time_and_every_guard() {
        let mut c = version_6();
        migrate(&mut c).unwrap();
        let mut indexes: Vec<String> = c
            .prepare(
                "SELECT name FROM sqlite_master WHERE type = 'index' AND tbl_name = 'calibrations' \
                 AND sql IS NOT NULL",
            )
            .unwrap()
            .query_map([], |r| r.get(0))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        indexes.sort();
        assert_eq!(indexes, ["calibrations_by_sensor_time"]);
        let plan: String = c
            .query_row(
                "EXPLAIN QUERY PLAN SELECT id FROM calibrations WHERE sensor_id = ?1 \
                 ORDER BY performed_at DESC, id DESC LIMIT 1",
                ["S-1"],
                |r| r.get(3),
            )
            .unwrap();
        assert!(plan.contains("calibrations_by_sensor_time"), "{plan}");
        let refused = |sql: &str| c.execute(sql, []).unwrap_err().to_string();
        assert!(
            refused("UPDATE calibrations SET unit = 'V'").contains("never changes"),
            "the immutability trigger"
        );
        let insert = "INSERT INTO calibrations (id, sensor_id, performed_at, received_at, unit, \
             model, runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
             expanded) VALUES ('c2', 'S-1', 'p', 'r', 'mA', '[]', 1, ";
        assert!(
            refused(&format!(
                "{insert}'{{\"k0\":\"x\"}}', '{{}}', '{{}}', x'', 't', 'p', NULL)"
            ))
            .contains("must be finite numbers")
        );
        assert!(
            refused(&format!(
                "{insert}'{{}}', '{{}}', '{{}}', x'', 't', 'p', '{{\"k0\":null}}')"
            ))
            .contains("expanded uncertainties must be finite numbers")
        );
        assert!(
            refused(
                "INSERT INTO calibrations (id, sensor_id, performed_at, received_at, unit, model, \
                 runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
                 verdict) VALUES ('c3', 'S', 'p', 'r', 'mA', '[]', 1, '{}', '{}', '{}', x'', \
                 't', 'p', 'maybe')"
            )
            .contains("CHECK constraint failed")
        );
    }

    #[test]
    fn references_to_the_rebuilt_table_still_hold() {
        let mut c = version_6();
        migrate(&mut c).unwrap();
        let keys: bool = c
            .pragma_query_value(None, "foreign_keys", |r| r.get(0))
            .unwrap();
        assert!(keys, "the connection's setting is restored");
        let e = c
            .execute("DELETE FROM calibrations WHERE id = 'c1'", [])
            .unwrap_err();
        assert!(e.to_string().contains("FOREIGN KEY"), "{e}");
        let e = c
            .execute(
                "UPDATE sensors SET latest_calibration_id = 'missing' WHERE sensor_id = ?1",
                params!["S-1"],
            )
            .unwrap_err();
        assert!(e.to_string().contains("FOREIGN KEY"), "{e}");
    }

    #[test]
    fn a_migration_that_would_leave_a_broken_reference_is_rolled_back() {
        let mut c = version_6();
        // A reference broken before the migration, as by a tool that wrote
        // to the file with foreign keys off.
        c.pragma_update(None, "foreign_keys", false).unwrap();
        c.execute(
            "UPDATE sensors SET latest_calibration_id = 'missing' WHERE sensor_id = 'S-1'",
            [],
        )
        .unwrap();
        let e = migrate(&mut c).unwrap_err();
        assert!(
            e.to_string().contains("broken reference in table sensors"),
            "{e}"
        );
        assert_eq!(version(&c), 6);
        let last: String = c
            .query_row(
                "SELECT name FROM pragma_table_info('calibrations') ORDER BY cid DESC LIMIT 1",
                [],
                |r| r.get(0),
            )
            .unwrap();
        assert_eq!(last, "expanded", "version 6's table, untouched");
    }

    #[test]
    fn a_connection_that_finds_the_work_done_under_the_lock_checks_nothing() {
        // Another connection migrated between this one's first read of the
        // version and its write lock: `apply` re-reads the version, finds
        // nothing to do and neither applies nor checks (a whole-database
        // check would be wasted, and a reference broken by some other tool
        // is not this open's business).
        let mut c = version_6();
        migrate(&mut c).unwrap();
        c.pragma_update(None, "foreign_keys", false).unwrap();
        c.execute(
            "UPDATE sensors SET latest_calibration_id = 'missing' WHERE sensor_id = 'S-1'",
            [],
        )
        .unwrap();
        apply(&mut c, MIGRATIONS.len() as i64).unwrap();
        assert_eq!(version(&c), MIGRATIONS.len() as i64);
    }
}
