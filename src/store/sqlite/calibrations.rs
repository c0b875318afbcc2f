//! Calibrations: the durable insert (with its sensor and idempotency key in
//! one transaction) and the reads of results, submissions and summaries.

use std::sync::LazyLock;

use async_trait::async_trait;
use bytes::Bytes;
use rusqlite::{Connection, params};
use uuid::Uuid;

use super::SqliteStore;
use super::errors::map;
use super::rows::{self, SUMMARY_COLUMNS};
use crate::domain::review::{Basis, State};
use crate::domain::timestamp::Timestamp;
use crate::store::{
    CalibrationSummary, Calibrations, HistoryQuery, IdempotencyKey, NEWEST_FIRST, NewCalibration,
    SENSOR_MERGE, SENSOR_ROW, SensorRow, Series, StoreError, Stored, StoredSubmission, counts,
};

/// The sensor's row after a calibration is stored, by [`SENSOR_MERGE`],
/// answered ([`SENSOR_ROW`]).
static UPSERT_SENSOR: LazyLock<String> = LazyLock::new(|| {
    format!(
        "INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
         latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at) \
         VALUES (?1, 1, ?2, ?2, ?3, ?4, ?5, ?6) {SENSOR_MERGE} {SENSOR_ROW}"
    )
});

/// One calibration's summary, by id.
static SUMMARY: LazyLock<String> =
    LazyLock::new(|| format!("SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.id = ?1"));

/// A page of a sensor's history: newest first, within `?2..=?3`, before the
/// calibration `?4`, at most `?5` (after the selected columns).
static HISTORY_PAGE: LazyLock<String> = LazyLock::new(|| {
    format!(
        "FROM calibrations c WHERE c.sensor_id = ?1 \
         AND (?2 IS NULL OR c.performed_at >= ?2) AND (?3 IS NULL OR c.performed_at <= ?3) \
         AND (?4 IS NULL OR (c.performed_at, c.id) < \
              (SELECT b.performed_at, b.id FROM calibrations b WHERE b.id = ?4)) \
         {NEWEST_FIRST} LIMIT ?5"
    )
});

/// The summaries of a page of a sensor's history.
static HISTORY: LazyLock<String> =
    LazyLock::new(|| format!("SELECT {SUMMARY_COLUMNS} {}", *HISTORY_PAGE));

/// The ids and states of a page of a sensor's history.
static HISTORY_IDS: LazyLock<String> = LazyLock::new(|| {
    format!(
        "SELECT c.id, {} AS state {}",
        crate::state_sql!(),
        *HISTORY_PAGE
    )
});

/// A sensor's latest calibrations that count on `basis` within
/// `?2..=?3`, at most `?4`.
fn series_sql(basis: Basis, whole: bool) -> String {
    let window = format!(
        "c.sensor_id = ?1 AND {} \
         AND (?2 IS NULL OR c.performed_at >= ?2) AND (?3 IS NULL OR c.performed_at <= ?3)",
        counts(basis)
    );
    format!(
        "WITH page AS MATERIALIZED (SELECT {SUMMARY_COLUMNS} FROM calibrations c \
         WHERE {window} {NEWEST_FIRST} LIMIT ?4) \
         SELECT page.*, {} AS in_window FROM page ORDER BY page.performed_at DESC, page.id DESC",
        crate::store::sql::in_window_sql("?4", &window, whole.then_some("?1"))
    )
}

/// A sensor's latest calibration that counts on `basis`, performed strictly
/// before `?2` when `before`, else the latest of all. Two statements, not
/// `?2 IS NULL OR …`: with that disjunction the index walk could not start
/// at `?2` and read every later calibration first (a late submission into
/// 100 000 took 17 ms, BENCHMARKS.md "A sensor's history").
fn previous_sql(basis: Basis, before: bool) -> String {
    format!(
        "SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.sensor_id = ?1 AND {} {} \
         {NEWEST_FIRST} LIMIT 1",
        counts(basis),
        if before {
            "AND c.performed_at < ?2"
        } else {
            ""
        }
    )
}

fn json<T: serde::Serialize>(v: &T) -> Result<String, StoreError> {
    serde_json::to_string(v).map_err(|e| StoreError::Refused(e.to_string()))
}

/// Stores a calibration, its sensor's summary and its key, inside a
/// transaction (the writer's savepoint, see [`super::writer`]) that the
/// caller commits when the answer is [`Stored::New`] and rolls back
/// otherwise: [`Stored::Existing`] has written a calibration row that must
/// not stay. With [`Stored::New`], the sensor's row as it left it.
pub(super) fn insert(
    tx: &Connection,
    n: NewCalibration,
    key: Option<IdempotencyKey>,
    inherited: &[crate::domain::nonconformity::Nonconformity],
    entry: &crate::store::audit::Submitted,
) -> Result<(Stored, Option<SensorRow>), StoreError> {
    n.check()?;
    let id = n.id.to_string();
    let performed_at = n.performed_at.to_string();
    let result = std::str::from_utf8(&n.result).map_err(|e| StoreError::Refused(e.to_string()))?;
    rows::execute(
        tx,
        "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, \
         model, runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
         sensor_type, verdict, due_at, expanded, triad, thermal) \
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20)",
        params![
            id,
            n.sensor_id,
            n.station_id,
            performed_at,
            n.received_at.to_string(),
            n.unit,
            json(&n.model)?,
            n.runs as i64,
            json(&n.coefficients)?,
            json(&n.std_errors)?,
            result,
            &n.submission[..],
            n.content_type,
            n.submitted_by,
            n.sensor_type,
            n.verdict.map(|v| v.as_str()),
            n.due_at.map(|t| t.to_string()),
            n.expanded.as_ref().map(json).transpose()?,
            n.triad.as_ref().map(json).transpose()?,
            n.thermal_json()?
        ],
    )?;
    if let Some(k) = key {
        // Record the key as done, unless a request with the same key
        // (after our lease expired) completed it first.
        let changed = rows::execute(
            tx,
            "INSERT INTO idempotency_keys (principal, key, request_hash, calibration_id, created_at) \
                 VALUES (?1, ?2, ?3, ?4, ?5) \
                 ON CONFLICT (principal, key) DO UPDATE SET calibration_id = excluded.calibration_id, \
                   locked_until = NULL WHERE idempotency_keys.calibration_id IS NULL",
            params![
                k.principal,
                k.key,
                k.request_hash.to_vec(),
                id,
                n.received_at.to_string()
            ],
        )?;
        if changed == 0 {
            let existing = rows::first(
                tx,
                "SELECT calibration_id FROM idempotency_keys WHERE principal = ?1 AND key = ?2",
                params![k.principal, k.key],
                |r| rows::uuid(r, "calibration_id"),
            )?
            .ok_or_else(|| {
                StoreError::corrupt("idempotency key", "vanished inside a transaction")
            })?;
            return Ok((Stored::Existing(existing), None));
        }
    }
    super::fitted::check(tx, &n)?;
    let row = rows::first(
        tx,
        &UPSERT_SENSOR,
        params![
            n.sensor_id,
            performed_at,
            id,
            n.sensor_type.as_ref().filter(|_| n.assigns_type),
            n.verdict.map(|v| v.as_str()),
            n.due_at.map(|t| t.to_string())
        ],
        rows::sensor_row,
    )?;
    let by = super::audit::submitter(tx, &n.submitted_by)?;
    let latest = row
        .as_ref()
        .is_some_and(|r| r.latest_calibration_id == n.id);
    let effect = crate::domain::events::Effect::stored(n.id, latest);
    super::audit::append(tx, entry.event(by, effect))?;
    super::holds::place(tx, &n, inherited, latest)?;
    Ok((Stored::New, row))
}

/// One of the [`HISTORY_PAGE`] queries, bound to `q`.
fn page<T>(
    conn: &Connection,
    sql: &str,
    sensor_id: &str,
    q: &HistoryQuery,
    decode: impl Fn(&rusqlite::Row<'_>) -> Result<T, StoreError>,
) -> Result<Vec<T>, StoreError> {
    let params = params![
        sensor_id,
        q.from.map(|t| t.to_string()),
        q.to.map(|t| t.to_string()),
        q.before.map(|id| id.to_string()),
        q.limit as i64
    ];
    rows::all(conn, sql, params, decode)
}

#[async_trait]
impl Calibrations for SqliteStore {
    /// In the writer's next batch; the sensor's cached summary is brought
    /// up to date once it is durable.
    async fn insert_calibration(
        &self,
        n: NewCalibration,
        key: Option<IdempotencyKey>,
    ) -> Result<Stored, StoreError> {
        n.check()?;
        self.follow_the_file()?;
        let this = self.clone();
        let summary = CalibrationSummary::from(&n);
        // One naming standards may be stored held: its sensor's entry is
        // dropped rather than kept as submitted.
        let may_hold = !n.standards.is_empty();
        // Its audit entry's digests here, beside the other requests, not in
        // the one writer.
        let entry = crate::store::audit::submitted(&n);
        let write = async move {
            this.write("insert_calibration", move |conn| {
                let stored = insert(conn, n, key, &[], &entry)?;
                let keep = stored.0 == Stored::New;
                Ok((stored, keep))
            })
            .await
        };
        if may_hold {
            let sensor = [summary.sensor_id.clone()];
            let written = async move { write.await.map(|(stored, _)| stored) };
            return self.cache.changing(&sensor, written).await;
        }
        self.cache.insert_calibration(summary, write).await
    }

    async fn calibration_result(&self, id: Uuid) -> Result<Option<Bytes>, StoreError> {
        self.run("calibration_result", move |conn| {
            rows::first(
                conn,
                "SELECT result FROM calibrations WHERE id = ?1",
                [id.to_string()],
                |r| {
                    let text: String = r.get("result").map_err(map)?;
                    Ok(Bytes::from(text))
                },
            )
        })
        .await
    }

    async fn submission(&self, id: Uuid) -> Result<Option<StoredSubmission>, StoreError> {
        self.run("submission", move |conn| {
            rows::first(
                conn,
                "SELECT content_type, submission FROM calibrations WHERE id = ?1",
                [id.to_string()],
                |r| {
                    Ok(StoredSubmission {
                        content_type: r.get("content_type").map_err(map)?,
                        body: Bytes::from(r.get::<_, Vec<u8>>("submission").map_err(map)?),
                    })
                },
            )
        })
        .await
    }

    async fn calibration_summary(
        &self,
        id: Uuid,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        self.run("calibration_summary", move |conn| {
            rows::first(conn, &SUMMARY, [id.to_string()], rows::summary)
        })
        .await
    }

    async fn history(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<CalibrationSummary>, StoreError> {
        self.run("history", move |conn| {
            page(conn, &HISTORY, &sensor_id, &q, rows::summary)
        })
        .await
    }

    async fn history_ids(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<(Uuid, State)>, StoreError> {
        self.run("history_ids", move |conn| {
            page(conn, &HISTORY_IDS, &sensor_id, &q, |row| {
                Ok((rows::uuid(row, "id")?, rows::state(row)?))
            })
        })
        .await
    }

    async fn series(
        &self,
        sensor_id: String,
        from: Option<Timestamp>,
        to: Option<Timestamp>,
        limit: usize,
        basis: Basis,
    ) -> Result<Series, StoreError> {
        self.run("series", move |conn| {
            let mut in_window = 0usize;
            let mut items = rows::all(
                conn,
                &series_sql(basis, crate::store::sql::whole_history(from, to, basis)),
                params![
                    sensor_id,
                    from.map(|t| t.to_string()),
                    to.map(|t| t.to_string()),
                    limit as i64
                ],
                |row| {
                    in_window = row.get::<_, i64>("in_window").map_err(map)? as usize;
                    rows::summary(row)
                },
            )?;
            items.reverse();
            Ok(Series { items, in_window })
        })
        .await
    }

    /// From the sensor's cached summary when it can tell
    /// ([`crate::store::cache::Cache::previous_calibration`]; the cache
    /// holds the sensor's latest on [`Basis::NotRejected`]).
    async fn previous_calibration(
        &self,
        sensor_id: String,
        before: Timestamp,
        basis: Basis,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        self.follow_the_file()?;
        if basis == Basis::NotRejected
            && let Some(hit) = self.cache.previous_calibration(&sensor_id, before)
        {
            return Ok(Some(hit));
        }
        self.run("previous_calibration", move |conn| {
            rows::first(
                conn,
                &previous_sql(basis, true),
                params![sensor_id, before.to_string()],
                rows::summary,
            )
        })
        .await
    }

    async fn latest_approved(
        &self,
        sensor_id: String,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        self.run("latest_approved", move |conn| {
            rows::first(
                conn,
                &previous_sql(Basis::ApprovedOnly, false),
                params![sensor_id],
                rows::summary,
            )
        })
        .await
    }

    async fn export_calibrations(
        &self,
        after: Option<Uuid>,
        limit: usize,
    ) -> Result<Vec<NewCalibration>, StoreError> {
        self.run("export_calibrations", move |conn| {
            let sql = format!(
                "SELECT {} FROM calibrations c WHERE (?1 IS NULL OR c.id > ?1) ORDER BY c.id LIMIT ?2",
                rows::RECORD_COLUMNS
            );
            rows::all(
                conn,
                &sql,
                params![after.map(|a| a.to_string()), limit as i64],
                rows::record,
            )
        })
        .await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The detail lines of `sql`'s query plan on a migrated, empty
    /// database.
    fn plan(sql: &str) -> Vec<String> {
        let mut c = Connection::open_in_memory().unwrap();
        super::super::migrations::migrate(&mut c).unwrap();
        let mut stmt = c.prepare(&format!("EXPLAIN QUERY PLAN {sql}")).unwrap();
        let nulls = vec![rusqlite::types::Null; stmt.parameter_count()];
        stmt.query_map(rusqlite::params_from_iter(nulls), |r| r.get::<_, String>(3))
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap()
    }

    /// What a submission, a review and a series read of a sensor's history
    /// goes by index, whatever the history's length: no statement scans
    /// the calibrations or the signatures (each did once, BENCHMARKS.md
    /// "A sensor's history").
    #[test]
    fn history_is_read_by_index() {
        for basis in [Basis::NotRejected, Basis::ApprovedOnly] {
            for sql in [
                previous_sql(basis, true),
                previous_sql(basis, false),
                series_sql(basis, false),
                series_sql(basis, true),
                crate::store::earlier_submitters_sql("?1"),
            ] {
                let plan = plan(&sql);
                let scans: Vec<&String> = plan
                    .iter()
                    .filter(|l| {
                        ["SCAN c", "SCAN s", "SCAN calibrations", "SCAN signatures"]
                            .iter()
                            .any(|t| l.starts_with(t))
                    })
                    .collect();
                assert!(scans.is_empty(), "{sql}: {plan:?}");
            }
            // The previous calibration's walk starts at its bound.
            let plan = plan(&previous_sql(basis, true));
            assert!(
                plan.iter()
                    .any(|l| l.contains("(sensor_id=? AND performed_at<?)")),
                "{plan:?}"
            );
        }
    }
}
