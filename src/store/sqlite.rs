//! The SQLite engine: one file, WAL journal, `synchronous=FULL`.
//!
//! A commit returns only once the WAL is on stable storage, so an
//! acknowledged calibration survives a crash or power loss; a transaction
//! interrupted by a crash is rolled back on the next open. Calls run on
//! tokio's blocking pool over a small pool of connections. A connection that
//! reported an error is dropped rather than reused, and every checkout checks
//! that the database file is still the one the connection opened, so the
//! service recovers by itself when a missing, replaced or read-only database
//! is put right. Migrations (`PRAGMA user_version`) are embedded and applied
//! whenever a connection opens a database that is behind.

use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use async_trait::async_trait;
use rusqlite::{
    Connection, ErrorCode, OpenFlags, OptionalExtension, Row, TransactionBehavior, params,
};
use serde_json::value::RawValue;
use uuid::Uuid;

use super::{
    CalibrationSummary, Claim, HistoryQuery, IDEMPOTENCY_RETENTION_SECONDS, IdempotencyKey,
    NewCalibration, SensorSummary, Store, StoreError, Stored, StoredSubmission, TokenRecord,
};
use crate::auth::Role;
use crate::timestamp::Timestamp;

/// Embedded migrations, applied in order; `user_version` counts those applied.
const MIGRATIONS: &[&str] = &[
    include_str!("migrations/sqlite/0001_init.sql"),
    include_str!("migrations/sqlite/0002_idempotency.sql"),
];

/// How long a statement waits for a lock held by another connection.
const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

/// Idle connections kept for reuse.
const POOL_SIZE: usize = 8;

/// Identity of the database file a connection opened.
type FileId = (u64, u64);

struct Pooled {
    conn: Connection,
    file: FileId,
}

struct Inner {
    path: PathBuf,
    idle: Mutex<Vec<Pooled>>,
}

/// A SQLite-backed [`Store`].
#[derive(Clone)]
pub struct SqliteStore {
    inner: Arc<Inner>,
}

fn unavailable(e: impl std::fmt::Display) -> StoreError {
    StoreError::Unavailable(e.to_string())
}

fn map_err(e: rusqlite::Error) -> StoreError {
    match e {
        rusqlite::Error::FromSqlConversionFailure(..)
        | rusqlite::Error::InvalidColumnType(..)
        | rusqlite::Error::IntegralValueOutOfRange(..) => StoreError::Corrupt(e.to_string()),
        rusqlite::Error::SqliteFailure(f, _) if f.code == ErrorCode::ConstraintViolation => {
            StoreError::Corrupt(e.to_string())
        }
        other => unavailable(other),
    }
}

fn file_id(path: &Path) -> Result<FileId, StoreError> {
    let meta = std::fs::metadata(path)
        .map_err(|e| unavailable(format!("database file {}: {e}", path.display())))?;
    Ok((meta.dev(), meta.ino()))
}

impl SqliteStore {
    /// Opens (creating if needed) the database at `path` and migrates it.
    pub fn open(path: impl Into<PathBuf>) -> Result<Self, StoreError> {
        let path = path.into();
        // Only the first open may create the file: later a missing file is an
        // outage to report, not an empty database to start afresh.
        let conn = Connection::open(&path).map_err(map_err)?;
        drop(conn);
        let store = SqliteStore {
            inner: Arc::new(Inner {
                path,
                idle: Mutex::new(Vec::new()),
            }),
        };
        let first = store.connect()?;
        // One process owns a SQLite database, so no request of an earlier
        // process can still be in flight: free the idempotency leases a
        // crash left behind, so that retries proceed at once instead of
        // waiting for the leases to expire.
        first
            .conn
            .execute(
                "UPDATE idempotency_keys SET locked_until = NULL \
                 WHERE calibration_id IS NULL AND locked_until IS NOT NULL",
                [],
            )
            .map_err(map_err)?;
        store.checkin(first);
        Ok(store)
    }

    /// The database file.
    pub fn path(&self) -> &Path {
        &self.inner.path
    }

    fn connect(&self) -> Result<Pooled, StoreError> {
        let path = &self.inner.path;
        let file = file_id(path)?;
        let flags = OpenFlags::SQLITE_OPEN_READ_WRITE
            | OpenFlags::SQLITE_OPEN_NO_MUTEX
            | OpenFlags::SQLITE_OPEN_URI;
        let mut conn = Connection::open_with_flags(path, flags).map_err(map_err)?;
        conn.busy_timeout(BUSY_TIMEOUT).map_err(map_err)?;
        conn.pragma_update_and_check(None, "journal_mode", "WAL", |r| r.get::<_, String>(0))
            .map_err(map_err)?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(map_err)?;
        conn.pragma_update(None, "foreign_keys", "ON")
            .map_err(map_err)?;
        migrate(&mut conn).map_err(map_err)?;
        Ok(Pooled { conn, file })
    }

    fn checkout(&self) -> Result<Pooled, StoreError> {
        let current = file_id(&self.inner.path);
        let mut idle = self.inner.idle.lock().expect("pool lock");
        match current {
            Err(e) => {
                idle.clear();
                return Err(e);
            }
            Ok(id) => idle.retain(|p| p.file == id),
        }
        let pooled = idle.pop();
        drop(idle);
        match pooled {
            Some(p) => Ok(p),
            None => self.connect(),
        }
    }

    fn checkin(&self, p: Pooled) {
        let mut idle = self.inner.idle.lock().expect("pool lock");
        if idle.len() < POOL_SIZE {
            idle.push(p);
        }
    }

    /// Runs `f` on a pooled connection on the blocking pool. A connection
    /// whose call failed is dropped, not returned.
    async fn run<T, F>(&self, f: F) -> Result<T, StoreError>
    where
        T: Send + 'static,
        F: FnOnce(&mut Connection) -> Result<T, StoreError> + Send + 'static,
    {
        let this = self.clone();
        tokio::task::spawn_blocking(move || {
            let mut p = this.checkout()?;
            let out = f(&mut p.conn);
            if out.is_ok() {
                this.checkin(p);
            }
            out
        })
        .await
        .map_err(|e| unavailable(format!("database task failed: {e}")))?
    }
}

fn migrate(conn: &mut Connection) -> rusqlite::Result<()> {
    let latest = MIGRATIONS.len() as i64;
    let version: i64 = conn.pragma_query_value(None, "user_version", |r| r.get(0))?;
    if version >= latest {
        return Ok(());
    }
    let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
    // Re-read under the write lock: another connection may have migrated.
    let version: i64 = tx.pragma_query_value(None, "user_version", |r| r.get(0))?;
    for sql in MIGRATIONS.iter().skip(version.max(0) as usize) {
        tx.execute_batch(sql)?;
    }
    tx.pragma_update(None, "user_version", latest)?;
    tx.commit()
}

/// Every row of a query, read by `row` (a cached statement).
fn all_rows<T>(
    c: &Connection,
    sql: &str,
    params: impl rusqlite::Params,
    row: impl FnMut(&Row<'_>) -> rusqlite::Result<T>,
) -> Result<Vec<T>, StoreError> {
    let mut stmt = c.prepare_cached(sql).map_err(map_err)?;
    stmt.query_map(params, row)
        .map_err(map_err)?
        .collect::<rusqlite::Result<Vec<_>>>()
        .map_err(map_err)
}

fn raw(s: String) -> Result<Box<RawValue>, StoreError> {
    RawValue::from_string(s).map_err(|e| StoreError::Corrupt(e.to_string()))
}

fn uuid(s: &str) -> Result<Uuid, StoreError> {
    Uuid::try_parse(s).map_err(|e| StoreError::Corrupt(format!("id {s:?}: {e}")))
}

const SUMMARY_COLUMNS: &str = "c.id, c.sensor_id, c.station_id, c.performed_at, c.received_at, \
     c.unit, c.model, c.runs, c.coefficients, c.std_errors";

/// Raw summary columns, decoded outside rusqlite's error type.
type SummaryRow = (
    String,
    String,
    Option<String>,
    String,
    String,
    String,
    String,
    i64,
    String,
    String,
);

fn summary_row(r: &Row<'_>, at: usize) -> rusqlite::Result<SummaryRow> {
    Ok((
        r.get(at)?,
        r.get(at + 1)?,
        r.get(at + 2)?,
        r.get(at + 3)?,
        r.get(at + 4)?,
        r.get(at + 5)?,
        r.get(at + 6)?,
        r.get(at + 7)?,
        r.get(at + 8)?,
        r.get(at + 9)?,
    ))
}

fn summary(row: SummaryRow) -> Result<CalibrationSummary, StoreError> {
    let (
        id,
        sensor_id,
        station_id,
        performed_at,
        received_at,
        unit,
        model,
        runs,
        coefficients,
        std_errors,
    ) = row;
    Ok(CalibrationSummary {
        id: uuid(&id)?,
        sensor_id,
        station_id,
        performed_at,
        received_at,
        unit,
        model: raw(model)?,
        runs: usize::try_from(runs).map_err(|e| StoreError::Corrupt(e.to_string()))?,
        coefficients: raw(coefficients)?,
        std_errors: raw(std_errors)?,
    })
}

type SensorRow = (String, i64, String, String, SummaryRow);

fn sensor_summary(row: SensorRow) -> Result<SensorSummary, StoreError> {
    let (sensor_id, count, first, latest_at, latest) = row;
    Ok(SensorSummary {
        sensor_id,
        calibration_count: u64::try_from(count).map_err(|e| StoreError::Corrupt(e.to_string()))?,
        first_performed_at: first,
        latest_performed_at: latest_at,
        latest: summary(latest)?,
    })
}

fn sensor_query(filter: &str) -> String {
    format!(
        "SELECT s.sensor_id, s.calibration_count, s.first_performed_at, s.latest_performed_at, {SUMMARY_COLUMNS} \
         FROM sensors s JOIN calibrations c ON c.id = s.latest_calibration_id {filter}"
    )
}

fn sensor_row(r: &Row<'_>) -> rusqlite::Result<SensorRow> {
    Ok((
        r.get(0)?,
        r.get(1)?,
        r.get(2)?,
        r.get(3)?,
        summary_row(r, 4)?,
    ))
}

type TokenRow = (
    String,
    Vec<u8>,
    String,
    Option<String>,
    Option<String>,
    String,
    Option<String>,
);

const TOKEN_COLUMNS: &str = "id, secret_hash, role, station_id, label, created_at, revoked_at";

fn token_row(r: &Row<'_>) -> rusqlite::Result<TokenRow> {
    Ok((
        r.get(0)?,
        r.get(1)?,
        r.get(2)?,
        r.get(3)?,
        r.get(4)?,
        r.get(5)?,
        r.get(6)?,
    ))
}

fn token(row: TokenRow) -> Result<TokenRecord, StoreError> {
    let (id, secret_hash, role, station_id, label, created_at, revoked_at) = row;
    Ok(TokenRecord {
        id: uuid(&id)?,
        secret_hash,
        role: Role::parse(&role).ok_or_else(|| StoreError::Corrupt(format!("role {role:?}")))?,
        station_id,
        label,
        created_at,
        revoked_at,
    })
}

#[async_trait]
impl Store for SqliteStore {
    async fn ping(&self) -> Result<(), StoreError> {
        self.run(|c| {
            c.query_row("SELECT count(*) FROM sensors", [], |r| r.get::<_, i64>(0))
                .map_err(map_err)?;
            Ok(())
        })
        .await
    }

    async fn insert_calibration(
        &self,
        n: NewCalibration,
        key: Option<IdempotencyKey>,
    ) -> Result<Stored, StoreError> {
        self.run(move |c| {
            let tx = c
                .transaction_with_behavior(TransactionBehavior::Immediate)
                .map_err(map_err)?;
            let id = n.id.to_string();
            let performed_at = n.performed_at.to_string();
            tx.execute(
                "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, \
                 model, runs, coefficients, std_errors, result, submission, content_type, submitted_by) \
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)",
                params![
                    id,
                    n.sensor_id,
                    n.station_id,
                    performed_at,
                    n.received_at.to_string(),
                    n.unit,
                    n.model,
                    n.runs as i64,
                    n.coefficients,
                    n.std_errors,
                    n.result,
                    n.submission,
                    n.content_type,
                    n.submitted_by
                ],
            )
            .map_err(map_err)?;
            if let Some(k) = key {
                // Record the key as done, unless a request with the same key
                // (after our lease expired) completed it first.
                let changed = tx
                    .execute(
                        "INSERT INTO idempotency_keys (principal, key, request_hash, calibration_id, created_at) \
                         VALUES (?1, ?2, ?3, ?4, ?5) \
                         ON CONFLICT (principal, key) DO UPDATE SET calibration_id = excluded.calibration_id, \
                           locked_until = NULL WHERE idempotency_keys.calibration_id IS NULL",
                        params![k.principal, k.key, k.request_hash.to_vec(), id, n.received_at.to_string()],
                    )
                    .map_err(map_err)?;
                if changed == 0 {
                    let existing: String = tx
                        .query_row(
                            "SELECT calibration_id FROM idempotency_keys WHERE principal = ?1 AND key = ?2",
                            params![k.principal, k.key],
                            |r| r.get(0),
                        )
                        .map_err(map_err)?;
                    drop(tx);
                    return Ok(Stored::Existing(uuid(&existing)?));
                }
            }
            tx.execute(
                "INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
                 latest_performed_at, latest_calibration_id) VALUES (?1, 1, ?2, ?2, ?3) \
                 ON CONFLICT (sensor_id) DO UPDATE SET \
                   calibration_count = calibration_count + 1, \
                   first_performed_at = min(first_performed_at, excluded.first_performed_at), \
                   latest_calibration_id = CASE WHEN (excluded.latest_performed_at, excluded.latest_calibration_id) \
                       > (latest_performed_at, latest_calibration_id) \
                       THEN excluded.latest_calibration_id ELSE latest_calibration_id END, \
                   latest_performed_at = max(latest_performed_at, excluded.latest_performed_at)",
                params![n.sensor_id, performed_at, id],
            )
            .map_err(map_err)?;
            tx.commit().map_err(map_err)?;
            Ok(Stored::New)
        })
        .await
    }

    async fn claim_key(
        &self,
        k: IdempotencyKey,
        now: Timestamp,
        lease_until: Timestamp,
    ) -> Result<Claim, StoreError> {
        self.run(move |c| {
            let tx = c
                .transaction_with_behavior(TransactionBehavior::Immediate)
                .map_err(map_err)?;
            let horizon = now.plus_seconds(-IDEMPOTENCY_RETENTION_SECONDS).to_string();
            tx.execute("DELETE FROM idempotency_keys WHERE created_at < ?1", [horizon])
                .map_err(map_err)?;
            let row: Option<(Vec<u8>, Option<String>, Option<String>)> = tx
                .query_row(
                    "SELECT request_hash, calibration_id, locked_until FROM idempotency_keys \
                     WHERE principal = ?1 AND key = ?2",
                    params![k.principal, k.key],
                    |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
                )
                .optional()
                .map_err(map_err)?;
            let now_text = now.to_string();
            let claim = match row {
                Some((hash, _, _)) if hash != k.request_hash => Claim::Mismatch,
                Some((_, Some(id), _)) => Claim::Done(uuid(&id)?),
                Some((_, None, Some(until))) if until > now_text => Claim::InFlight,
                Some(_) => {
                    tx.execute(
                        "UPDATE idempotency_keys SET locked_until = ?3 WHERE principal = ?1 AND key = ?2",
                        params![k.principal, k.key, lease_until.to_string()],
                    )
                    .map_err(map_err)?;
                    Claim::Fresh
                }
                None => {
                    tx.execute(
                        "INSERT INTO idempotency_keys (principal, key, request_hash, locked_until, created_at) \
                         VALUES (?1, ?2, ?3, ?4, ?5)",
                        params![k.principal, k.key, k.request_hash.to_vec(), lease_until.to_string(), now_text],
                    )
                    .map_err(map_err)?;
                    Claim::Fresh
                }
            };
            tx.commit().map_err(map_err)?;
            Ok(claim)
        })
        .await
    }

    async fn release_key(&self, principal: String, key: String) -> Result<(), StoreError> {
        self.run(move |c| {
            c.execute(
                "DELETE FROM idempotency_keys WHERE principal = ?1 AND key = ?2 AND calibration_id IS NULL",
                params![principal, key],
            )
            .map_err(map_err)?;
            Ok(())
        })
        .await
    }

    async fn calibration_result(&self, id: Uuid) -> Result<Option<String>, StoreError> {
        self.run(move |c| {
            c.query_row(
                "SELECT result FROM calibrations WHERE id = ?1",
                [id.to_string()],
                |r| r.get(0),
            )
            .optional()
            .map_err(map_err)
        })
        .await
    }

    async fn submission(&self, id: Uuid) -> Result<Option<StoredSubmission>, StoreError> {
        self.run(move |c| {
            c.query_row(
                "SELECT content_type, submission FROM calibrations WHERE id = ?1",
                [id.to_string()],
                |r| {
                    Ok(StoredSubmission {
                        content_type: r.get(0)?,
                        body: r.get(1)?,
                    })
                },
            )
            .optional()
            .map_err(map_err)
        })
        .await
    }

    async fn calibration_summary(
        &self,
        id: Uuid,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        self.run(move |c| {
            let row = c
                .query_row(
                    &format!("SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.id = ?1"),
                    [id.to_string()],
                    |r| summary_row(r, 0),
                )
                .optional()
                .map_err(map_err)?;
            row.map(summary).transpose()
        })
        .await
    }

    async fn sensors(
        &self,
        after: Option<String>,
        limit: usize,
    ) -> Result<Vec<SensorSummary>, StoreError> {
        self.run(move |c| {
            let sql =
                sensor_query("WHERE ?1 IS NULL OR s.sensor_id > ?1 ORDER BY s.sensor_id LIMIT ?2");
            all_rows(c, &sql, params![after, limit as i64], sensor_row)?
                .into_iter()
                .map(sensor_summary)
                .collect()
        })
        .await
    }

    async fn sensor(&self, sensor_id: String) -> Result<Option<SensorSummary>, StoreError> {
        self.run(move |c| {
            let row = c
                .query_row(
                    &sensor_query("WHERE s.sensor_id = ?1"),
                    [sensor_id],
                    sensor_row,
                )
                .optional()
                .map_err(map_err)?;
            row.map(sensor_summary).transpose()
        })
        .await
    }

    async fn history(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<CalibrationSummary>, StoreError> {
        self.run(move |c| {
            let sql = format!(
                "SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.sensor_id = ?1 \
                 AND (?2 IS NULL OR c.performed_at >= ?2) AND (?3 IS NULL OR c.performed_at <= ?3) \
                 AND (?4 IS NULL OR (c.performed_at, c.id) < \
                      (SELECT b.performed_at, b.id FROM calibrations b WHERE b.id = ?4)) \
                 ORDER BY c.performed_at DESC, c.id DESC LIMIT ?5"
            );
            let params = params![
                sensor_id,
                q.from.map(|t| t.to_string()),
                q.to.map(|t| t.to_string()),
                q.before.map(|id| id.to_string()),
                q.limit as i64
            ];
            all_rows(c, &sql, params, |r| summary_row(r, 0))?
                .into_iter()
                .map(summary)
                .collect()
        })
        .await
    }

    async fn insert_token(&self, t: TokenRecord) -> Result<(), StoreError> {
        self.run(move |c| {
            c.execute(
                &format!(
                    "INSERT INTO tokens ({TOKEN_COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)"
                ),
                params![
                    t.id.to_string(),
                    t.secret_hash,
                    t.role.as_str(),
                    t.station_id,
                    t.label,
                    t.created_at,
                    t.revoked_at
                ],
            )
            .map_err(map_err)?;
            Ok(())
        })
        .await
    }

    async fn token(&self, id: Uuid) -> Result<Option<TokenRecord>, StoreError> {
        self.run(move |c| {
            let row = c
                .query_row(
                    &format!("SELECT {TOKEN_COLUMNS} FROM tokens WHERE id = ?1"),
                    [id.to_string()],
                    token_row,
                )
                .optional()
                .map_err(map_err)?;
            row.map(token).transpose()
        })
        .await
    }

    async fn tokens(&self) -> Result<Vec<TokenRecord>, StoreError> {
        self.run(|c| {
            let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens ORDER BY id");
            all_rows(c, &sql, [], token_row)?
                .into_iter()
                .map(token)
                .collect()
        })
        .await
    }

    async fn revoke_token(&self, id: Uuid, at: Timestamp) -> Result<bool, StoreError> {
        self.run(move |c| {
            let n = c
                .execute(
                    "UPDATE tokens SET revoked_at = ?2 WHERE id = ?1 AND revoked_at IS NULL",
                    params![id.to_string(), at.to_string()],
                )
                .map_err(map_err)?;
            Ok(n == 1)
        })
        .await
    }

    async fn has_admin_token(&self) -> Result<bool, StoreError> {
        self.run(|c| {
            c.query_row(
                "SELECT EXISTS (SELECT 1 FROM tokens WHERE role = 'admin' AND revoked_at IS NULL)",
                [],
                |r| r.get(0),
            )
            .map_err(map_err)
        })
        .await
    }

    async fn close(&self) {
        let this = self.clone();
        let _ = tokio::task::spawn_blocking(move || {
            let conns: Vec<Pooled> =
                std::mem::take(&mut *this.inner.idle.lock().expect("pool lock"));
            if let Some(p) = conns.first() {
                // Fold the WAL back into the main file so a copy of the
                // database file alone is complete.
                if let Err(e) = p
                    .conn
                    .query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |_| Ok(()))
                {
                    tracing::warn!(error = %e, "WAL checkpoint at shutdown failed");
                }
            }
            drop(conns);
        })
        .await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rusqlite::ffi;

    fn failure(code: i32) -> rusqlite::Error {
        rusqlite::Error::SqliteFailure(ffi::Error::new(code), None)
    }

    #[test]
    fn database_outages_are_unavailable_and_bugs_are_not() {
        for code in [
            ffi::SQLITE_BUSY,
            ffi::SQLITE_LOCKED,
            ffi::SQLITE_READONLY,
            ffi::SQLITE_FULL,
            ffi::SQLITE_IOERR,
            ffi::SQLITE_CANTOPEN,
            ffi::SQLITE_CORRUPT,
        ] {
            assert!(
                matches!(map_err(failure(code)), StoreError::Unavailable(_)),
                "code {code}"
            );
        }
        assert!(matches!(
            map_err(failure(ffi::SQLITE_CONSTRAINT)),
            StoreError::Corrupt(_)
        ));
        let decode =
            rusqlite::Error::InvalidColumnType(0, "id".into(), rusqlite::types::Type::Null);
        assert!(matches!(map_err(decode), StoreError::Corrupt(_)));
    }

    #[test]
    fn a_missing_file_is_not_recreated_after_the_first_open() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gone.db");
        let store = SqliteStore::open(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(store.checkout(), Err(StoreError::Unavailable(_))));
        assert!(!path.exists());
    }
}
