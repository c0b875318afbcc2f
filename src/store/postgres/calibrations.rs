//! Calibrations: the durable insert (with its sensor and idempotency key in
//! one transaction) and the reads of results, submissions and summaries.
//!
//! A calibration is written by [`write`] inside a transaction that is
//! either its own ([`insert`]) or its batch's ([`writer`](super::writer)).
//!
//! Under READ COMMITTED, the sensor's upsert locks its row: concurrent
//! inserts for one sensor — from any replica — apply one after the other,
//! each to the row as the other left it, so no count or "latest" is lost.
//! An idempotency key is looked at under its row lock before anything is
//! written, and completed by an upsert guarded by `calibration_id IS NULL`:
//! of two requests completing one key at once, the second waits for the
//! first's lock and finds the key completed, so it writes nothing.

use std::time::Instant;

use async_trait::async_trait;
use bytes::Bytes;
use deadpool_postgres::{Object, Transaction};
use uuid::Uuid;

use super::PostgresStore;
use super::errors::map;
use super::rows::{self, RECORD_COLUMNS, SUMMARY_COLUMNS};
use crate::domain::review::{Basis, State};
use crate::domain::timestamp::Timestamp;
use crate::store::{
    CalibrationSummary, Calibrations, HistoryQuery, IdempotencyKey, NEWEST_FIRST, NewCalibration,
    SENSOR_MERGE, SENSOR_ROW, SensorRow, Series, StoreError, Stored, StoredSubmission, counts,
    observe,
};
use history::page;

/// A sensor's latest calibration that counts on `basis`, performed strictly
/// before `$2` when `before`, else the latest of all (two statements, not
/// `$2 IS NULL OR …`, whose generic plan cannot start the index walk at
/// `$2`).
fn previous_sql(basis: Basis, before: bool) -> String {
    format!(
        "SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.sensor_id = $1 AND {} {} \
         {NEWEST_FIRST} LIMIT 1",
        counts(basis),
        if before {
            "AND c.performed_at < $2"
        } else {
            ""
        }
    )
}

fn json<T: serde::Serialize>(v: &T) -> Result<String, StoreError> {
    serde_json::to_string(v).map_err(|e| StoreError::Refused(e.to_string()))
}

/// A calibration ready to bind: checked, its maps rendered as JSON text.
pub struct Row {
    n: NewCalibration,
    model: String,
    coefficients: String,
    std_errors: String,
    expanded: Option<String>,
    triad: Option<String>,
    thermal: Option<String>,
    runs: i32,
    entry: crate::store::audit::Submitted,
}

impl Row {
    /// Checks `n` (nothing non-finite) and renders what is stored as JSON.
    pub fn new(n: NewCalibration) -> Result<Self, StoreError> {
        n.check()?;
        std::str::from_utf8(&n.result).map_err(|e| StoreError::Refused(e.to_string()))?;
        Ok(Row {
            model: json(&n.model)?,
            coefficients: json(&n.coefficients)?,
            std_errors: json(&n.std_errors)?,
            expanded: n.expanded.as_ref().map(json).transpose()?,
            triad: n.triad.as_ref().map(json).transpose()?,
            thermal: n.thermal_json()?,
            runs: i32::try_from(n.runs).map_err(|e| StoreError::Refused(e.to_string()))?,
            entry: crate::store::audit::submitted(&n),
            n,
        })
    }

    /// The sensor the calibration is of.
    pub fn sensor_id(&self) -> &str {
        &self.n.sensor_id
    }

    /// The calibration.
    pub fn new_calibration(&self) -> &NewCalibration {
        &self.n
    }

    /// Its `calibration.submitted` entry, but for actor and effect.
    pub fn entry(&self) -> &crate::store::audit::Submitted {
        &self.entry
    }

    /// The model's terms, as JSON.
    pub fn model(&self) -> &str {
        &self.model
    }

    /// The fused coefficients, as JSON.
    pub fn coefficients(&self) -> &str {
        &self.coefficients
    }

    /// Their standard errors, as JSON.
    pub fn std_errors(&self) -> &str {
        &self.std_errors
    }

    /// Their expanded uncertainties, as JSON, if computed.
    pub fn expanded(&self) -> Option<&str> {
        self.expanded.as_deref()
    }

    /// A triad's elements, as JSON.
    pub fn triad(&self) -> Option<&str> {
        self.triad.as_deref()
    }

    /// A temperature model, as JSON.
    pub fn thermal(&self) -> Option<&str> {
        self.thermal.as_deref()
    }

    /// The number of runs.
    pub fn runs(&self) -> i32 {
        self.runs
    }

    /// The result document, as text (checked UTF-8 by [`Row::new`]).
    pub fn result(&self) -> Result<&str, StoreError> {
        std::str::from_utf8(&self.n.result).map_err(|e| StoreError::Refused(e.to_string()))
    }
}

/// What writing one calibration inside an open transaction came to.
pub enum Written {
    /// Stored (once the transaction commits), leaving its sensor's row so.
    New(SensorRow),
    /// The key was already completed by this calibration: nothing written.
    Existing(Uuid),
    /// Another request completed the key between this one's look at it and
    /// its own completion: the calibration was written, and the transaction
    /// must be rolled back.
    Raced,
}

/// Writes a calibration, its key and its sensor's summary in `tx`.
///
/// The key is looked at first, under its row lock (`FOR UPDATE`): a key
/// already completed writes nothing, so a transaction holding several
/// calibrations (the [`writer`](super::writer)'s batches) never has to undo
/// one of them. Only a key row that did not exist at the look and was
/// completed by another request before this one's completion ends in
/// [`Written::Raced`].
pub async fn write(
    tx: &Transaction<'_>,
    row: &Row,
    key: Option<&IdempotencyKey>,
) -> Result<Written, StoreError> {
    let n = &row.n;
    if let Some(k) = key {
        let look = tx
            .prepare_cached(
                "SELECT calibration_id FROM idempotency_keys \
                 WHERE principal = $1 AND key = $2 FOR UPDATE",
            )
            .await
            .map_err(map)?;
        if let Some(found) = tx
            .query_opt(&look, &[&k.principal, &k.key])
            .await
            .map_err(map)?
            && let Some(existing) = rows::get::<Option<Uuid>>(&found, "calibration_id")?
        {
            return Ok(Written::Existing(existing));
        }
    }
    super::fitted::check(tx, n).await?;
    let performed_at = n.performed_at.datetime();
    let verdict = n.verdict.map(|v| v.as_str());
    let due_at = n.due_at.map(|t| t.datetime());
    let result = std::str::from_utf8(&n.result).map_err(|e| StoreError::Refused(e.to_string()))?;
    let insert = tx
        .prepare_cached(
            "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, \
             model, runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
             sensor_type, verdict, due_at, expanded, triad, thermal) \
             VALUES ($1, $2, $3, $4, $5, $6, $7::text::json, $8, $9::text::json, $10::text::json, \
             $11, $12, $13, $14, $15, $16, $17, $18::text::json, $19::text::json, $20::text::json)",
        )
        .await
        .map_err(map)?;
    tx.execute(
        &insert,
        &[
            &n.id,
            &n.sensor_id,
            &n.station_id,
            &performed_at,
            &n.received_at.datetime(),
            &n.unit,
            &row.model,
            &row.runs,
            &row.coefficients,
            &row.std_errors,
            &result,
            &&n.submission[..],
            &n.content_type,
            &n.submitted_by,
            &n.sensor_type,
            &verdict,
            &due_at,
            &row.expanded,
            &row.triad,
            &row.thermal,
        ],
    )
    .await
    .map_err(map)?;
    if let Some(k) = key {
        let done = tx
            .prepare_cached(
                "INSERT INTO idempotency_keys (principal, key, request_hash, calibration_id, created_at) \
                 VALUES ($1, $2, $3, $4, $5) \
                 ON CONFLICT (principal, key) DO UPDATE SET calibration_id = excluded.calibration_id, \
                   locked_until = NULL, holder = NULL WHERE idempotency_keys.calibration_id IS NULL",
            )
            .await
            .map_err(map)?;
        let changed = tx
            .execute(
                &done,
                &[
                    &k.principal,
                    &k.key,
                    &&k.request_hash[..],
                    &n.id,
                    &n.received_at.datetime(),
                ],
            )
            .await
            .map_err(map)?;
        if changed == 0 {
            return Ok(Written::Raced);
        }
    }
    let sensor = tx
        .prepare_cached(&format!(
            "INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
             latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at) \
             VALUES ($1, 1, $2, $2, $3, $4, $5, $6) {SENSOR_MERGE} {SENSOR_ROW}"
        ))
        .await
        .map_err(map)?;
    let assigned = n.sensor_type.as_ref().filter(|_| n.assigns_type);
    let merged = tx
        .query_one(
            &sensor,
            &[
                &n.sensor_id,
                &performed_at,
                &n.id,
                &assigned,
                &verdict,
                &due_at,
            ],
        )
        .await
        .map_err(map)?;
    Ok(Written::New(rows::sensor_row(&merged)?))
}

/// Stores one calibration, its sensor's summary, its key and its audit
/// entry in a transaction of its own; the commit returns once it is durable
/// (`synchronous_commit=on`). Of two requests completing one key at once,
/// the second waits for the first's row lock, finds the key completed, and
/// stores nothing.
pub async fn insert(
    client: &mut Object,
    row: &Row,
    key: Option<&IdempotencyKey>,
) -> Result<(Stored, Option<SensorRow>), StoreError> {
    let tx = client.transaction().await.map_err(map)?;
    super::holds::lock(&tx, &row.n).await?;
    match write(&tx, row, key).await? {
        Written::New(sensor) => {
            let latest = sensor.latest_calibration_id == row.n.id;
            let mut events = super::audit::stored(&tx, &[(&row.n, &row.entry, latest)]).await?;
            events.extend(super::holds::place(&tx, &row.n, &[], latest).await?);
            super::audit::append(&tx, events).await?;
            tx.commit().await.map_err(map)?;
            Ok((Stored::New, Some(sensor)))
        }
        Written::Existing(id) => {
            tx.rollback().await.map_err(map)?;
            Ok((Stored::Existing(id), None))
        }
        Written::Raced => {
            tx.rollback().await.map_err(map)?;
            let k =
                key.ok_or_else(|| StoreError::corrupt("idempotency key", "raced without a key"))?;
            let row = client
                .query_one(
                    "SELECT calibration_id FROM idempotency_keys WHERE principal = $1 AND key = $2",
                    &[&k.principal, &k.key],
                )
                .await
                .map_err(map)?;
            let existing: Option<Uuid> = rows::get(&row, "calibration_id")?;
            let existing = existing.ok_or_else(|| {
                StoreError::corrupt("idempotency key", "completed without a calibration")
            })?;
            Ok((Stored::Existing(existing), None))
        }
    }
}

#[async_trait]
impl Calibrations for PostgresStore {
    /// In the writer's next batch; the sensor's cached summary is brought
    /// up to date once it is durable.
    async fn insert_calibration(
        &self,
        n: NewCalibration,
        key: Option<IdempotencyKey>,
    ) -> Result<Stored, StoreError> {
        let started = Instant::now();
        let row = Row::new(n);
        let out = match row {
            // One naming standards may be stored held: in a transaction of
            // its own that locks them first ([`super::holds`]), its
            // sensor's cached entry dropped rather than kept as submitted;
            // so is a model fitted from stored calibrations, which locks
            // them ([`super::fitted`]).
            Ok(row) if row.new_calibration().stored_alone() => {
                let sensor = [row.sensor_id().to_owned()];
                let this = self.clone();
                let write = async move {
                    act!(this, "insert_calibration", |client| {
                        insert(&mut client, &row, key.as_ref())
                            .await
                            .map(|(stored, _)| stored)
                    })
                };
                self.cache.changing(&sensor, write).await
            }
            Ok(row) => {
                let c = CalibrationSummary::from(row.new_calibration());
                let writer = self.writer.clone();
                self.cache
                    .insert_calibration(c, async move { writer.insert(row, key).await })
                    .await
            }
            Err(e) => Err(e),
        };
        observe("insert_calibration", started, &out);
        out
    }

    async fn calibration_result(&self, id: Uuid) -> Result<Option<Bytes>, StoreError> {
        op!(self, "calibration_result", |client| {
            let stmt = client
                .prepare_cached("SELECT result FROM calibrations WHERE id = $1")
                .await
                .map_err(map)?;
            let row = client.query_opt(&stmt, &[&id]).await.map_err(map)?;
            row.map(|r| rows::get::<String>(&r, "result").map(Bytes::from))
                .transpose()
        })
    }

    async fn submission(&self, id: Uuid) -> Result<Option<StoredSubmission>, StoreError> {
        op!(self, "submission", |client| {
            let stmt = client
                .prepare_cached("SELECT content_type, submission FROM calibrations WHERE id = $1")
                .await
                .map_err(map)?;
            let row = client.query_opt(&stmt, &[&id]).await.map_err(map)?;
            row.map(|r| {
                Ok(StoredSubmission {
                    content_type: rows::get(&r, "content_type")?,
                    body: Bytes::from(rows::get::<Vec<u8>>(&r, "submission")?),
                })
            })
            .transpose()
        })
    }

    async fn calibration_summary(
        &self,
        id: Uuid,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        op!(self, "calibration_summary", |client| {
            let sql = format!("SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.id = $1");
            let stmt = client.prepare_cached(&sql).await.map_err(map)?;
            let row = client.query_opt(&stmt, &[&id]).await.map_err(map)?;
            row.as_ref().map(rows::summary).transpose()
        })
    }

    async fn history(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<CalibrationSummary>, StoreError> {
        op!(self, "history", |client| {
            let select = format!("SELECT {SUMMARY_COLUMNS}");
            let found = page(&client, &select, &sensor_id, &q).await?;
            found.iter().map(rows::summary).collect()
        })
    }

    async fn history_ids(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<(Uuid, State)>, StoreError> {
        op!(self, "history_ids", |client| {
            let select = concat!("SELECT c.id, ", crate::state_sql!(), " AS state");
            let found = page(&client, select, &sensor_id, &q).await?;
            found
                .iter()
                .map(|r| Ok((rows::get(r, "id")?, rows::state(r)?)))
                .collect()
        })
    }

    async fn series(
        &self,
        sensor_id: String,
        from: Option<Timestamp>,
        to: Option<Timestamp>,
        limit: usize,
        basis: Basis,
    ) -> Result<Series, StoreError> {
        op!(self, "series", |client| {
            let window = format!(
                "c.sensor_id = $1 AND {} \
                 AND ($2::timestamptz IS NULL OR c.performed_at >= $2) \
                 AND ($3::timestamptz IS NULL OR c.performed_at <= $3)",
                counts(basis)
            );
            let sql = format!(
                "WITH page AS MATERIALIZED (SELECT {SUMMARY_COLUMNS} FROM calibrations c \
                 WHERE {window} {NEWEST_FIRST} LIMIT $4) \
                 SELECT page.*, {} AS in_window FROM page \
                 ORDER BY page.performed_at DESC, page.id DESC",
                crate::store::sql::in_window_sql(
                    "$4",
                    &window,
                    crate::store::sql::whole_history(from, to, basis).then_some("$1")
                )
            );
            let stmt = client.prepare_cached(&sql).await.map_err(map)?;
            let found = client
                .query(
                    &stmt,
                    &[
                        &sensor_id,
                        &from.map(|t| t.datetime()),
                        &to.map(|t| t.datetime()),
                        &(limit as i64),
                    ],
                )
                .await
                .map_err(map)?;
            let in_window = found
                .first()
                .map_or(0, |r| r.get::<_, i64>("in_window") as usize);
            let mut items = found
                .iter()
                .map(rows::summary)
                .collect::<Result<Vec<_>, _>>()?;
            items.reverse();
            Ok(Series { items, in_window })
        })
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
        if basis == Basis::NotRejected
            && let Some(hit) = self.cache.previous_calibration(&sensor_id, before)
        {
            return Ok(Some(hit));
        }
        op!(self, "previous_calibration", |client| {
            let stmt = client
                .prepare_cached(&previous_sql(basis, true))
                .await
                .map_err(map)?;
            let row = client
                .query_opt(&stmt, &[&sensor_id, &Some(before.datetime())])
                .await
                .map_err(map)?;
            row.as_ref().map(rows::summary).transpose()
        })
    }

    async fn latest_approved(
        &self,
        sensor_id: String,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        op!(self, "latest_approved", |client| {
            let stmt = client
                .prepare_cached(&previous_sql(Basis::ApprovedOnly, false))
                .await
                .map_err(map)?;
            let row = client.query_opt(&stmt, &[&sensor_id]).await.map_err(map)?;
            row.as_ref().map(rows::summary).transpose()
        })
    }

    async fn export_calibrations(
        &self,
        after: Option<Uuid>,
        limit: usize,
    ) -> Result<Vec<NewCalibration>, StoreError> {
        op!(self, "export_calibrations", |client| {
            let sql = format!(
                "SELECT {RECORD_COLUMNS} FROM calibrations c WHERE ($1::uuid IS NULL OR c.id > $1) \
             ORDER BY c.id LIMIT $2"
            );
            let found = client
                .query(&sql, &[&after, &(limit as i64)])
                .await
                .map_err(map)?;
            found.iter().map(rows::record).collect()
        })
    }
}

mod history;
#[cfg(test)]
mod tests;
