//! Calibrations: the durable insert (with its sensor and idempotency key in
//! one transaction) and the reads of results, submissions and summaries.
//!
//! Under READ COMMITTED, the sensor's upsert locks its row: concurrent
//! inserts for one sensor — from any replica — apply one after the other,
//! each to the row as the other left it, so no count or "latest" is lost.
//! Completing an idempotency key is an upsert guarded by `calibration_id IS
//! NULL`: of two requests completing one key at once, the second waits for
//! the first, finds the key completed, and rolls its own calibration back.

use bytes::Bytes;
use deadpool_postgres::Object;
use uuid::Uuid;

use super::errors::map;
use super::rows::{self, RECORD_COLUMNS, SUMMARY_COLUMNS};
use crate::domain::timestamp::Timestamp;
use crate::store::{
    CalibrationSummary, HistoryQuery, IdempotencyKey, NewCalibration, StoreError, Stored,
    StoredSubmission,
};

fn json<T: serde::Serialize>(v: &T) -> Result<String, StoreError> {
    serde_json::to_string(v).map_err(|e| StoreError::Refused(e.to_string()))
}

/// Stores a calibration, its sensor's summary and its key, atomically; the
/// commit returns once it is durable (`synchronous_commit=on`).
pub async fn insert(
    client: &mut Object,
    n: NewCalibration,
    key: Option<IdempotencyKey>,
) -> Result<Stored, StoreError> {
    n.check()?;
    let result = std::str::from_utf8(&n.result).map_err(|e| StoreError::Refused(e.to_string()))?;
    let (model, coefficients, std_errors) = (
        json(&n.model)?,
        json(&n.coefficients)?,
        json(&n.std_errors)?,
    );
    let expanded = n.expanded.as_ref().map(json).transpose()?;
    let runs = i32::try_from(n.runs).map_err(|e| StoreError::Refused(e.to_string()))?;
    let performed_at = n.performed_at.datetime();
    let verdict = n.verdict.map(|v| v.as_str());
    let due_at = n.due_at.map(|t| t.datetime());
    let tx = client.transaction().await.map_err(map)?;
    let insert = tx
        .prepare_cached(
            "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, \
             model, runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
             sensor_type, verdict, due_at, expanded) \
             VALUES ($1, $2, $3, $4, $5, $6, $7::text::json, $8, $9::text::json, $10::text::json, \
             $11, $12, $13, $14, $15, $16, $17, $18::text::json)",
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
            &model,
            &runs,
            &coefficients,
            &std_errors,
            &result,
            &&n.submission[..],
            &n.content_type,
            &n.submitted_by,
            &n.sensor_type,
            &verdict,
            &due_at,
            &expanded,
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
            let row = tx
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
            tx.rollback().await.map_err(map)?;
            return Ok(Stored::Existing(existing));
        }
    }
    // The new calibration becomes the latest when it is newer (performed_at,
    // then id); a type named by the submission becomes the sensor's.
    let newer = "(excluded.latest_performed_at, excluded.latest_calibration_id) \
                 > (sensors.latest_performed_at, sensors.latest_calibration_id)";
    let sensor = tx
        .prepare_cached(&format!(
            "INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
             latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at) \
             VALUES ($1, 1, $2, $2, $3, $4, $5, $6) \
             ON CONFLICT (sensor_id) DO UPDATE SET \
               calibration_count = sensors.calibration_count + 1, \
               first_performed_at = least(sensors.first_performed_at, excluded.first_performed_at), \
               latest_calibration_id = CASE WHEN {newer} THEN excluded.latest_calibration_id ELSE sensors.latest_calibration_id END, \
               latest_verdict = CASE WHEN {newer} THEN excluded.latest_verdict ELSE sensors.latest_verdict END, \
               latest_due_at = CASE WHEN {newer} THEN excluded.latest_due_at ELSE sensors.latest_due_at END, \
               latest_performed_at = greatest(sensors.latest_performed_at, excluded.latest_performed_at), \
               sensor_type = coalesce(excluded.sensor_type, sensors.sensor_type)"
        ))
        .await
        .map_err(map)?;
    let assigned = n.sensor_type.as_ref().filter(|_| n.assigns_type);
    tx.execute(
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
    tx.commit().await.map_err(map)?;
    Ok(Stored::New)
}

/// The stored result document.
pub async fn result(client: &Object, id: Uuid) -> Result<Option<Bytes>, StoreError> {
    let row = client
        .query_opt("SELECT result FROM calibrations WHERE id = $1", &[&id])
        .await
        .map_err(map)?;
    row.map(|r| rows::get::<String>(&r, "result").map(Bytes::from))
        .transpose()
}

/// The stored submission.
pub async fn submission(client: &Object, id: Uuid) -> Result<Option<StoredSubmission>, StoreError> {
    let row = client
        .query_opt(
            "SELECT content_type, submission FROM calibrations WHERE id = $1",
            &[&id],
        )
        .await
        .map_err(map)?;
    row.map(|r| {
        Ok(StoredSubmission {
            content_type: rows::get(&r, "content_type")?,
            body: Bytes::from(rows::get::<Vec<u8>>(&r, "submission")?),
        })
    })
    .transpose()
}

/// One calibration's summary.
pub async fn summary(client: &Object, id: Uuid) -> Result<Option<CalibrationSummary>, StoreError> {
    let sql = format!("SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.id = $1");
    let row = client.query_opt(&sql, &[&id]).await.map_err(map)?;
    row.as_ref().map(rows::summary).transpose()
}

/// A sensor's calibrations, newest `performed_at` first (ties: larger id).
pub async fn history(
    client: &Object,
    sensor_id: &str,
    q: &HistoryQuery,
) -> Result<Vec<CalibrationSummary>, StoreError> {
    let sql = format!(
        "SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.sensor_id = $1 \
         AND ($2::timestamptz IS NULL OR c.performed_at >= $2) \
         AND ($3::timestamptz IS NULL OR c.performed_at <= $3) \
         AND ($4::uuid IS NULL OR (c.performed_at, c.id) < \
              (SELECT b.performed_at, b.id FROM calibrations b WHERE b.id = $4)) \
         ORDER BY c.performed_at DESC, c.id DESC LIMIT $5"
    );
    let stmt = client.prepare_cached(&sql).await.map_err(map)?;
    let limit = q.limit as i64;
    let found = client
        .query(
            &stmt,
            &[
                &sensor_id,
                &q.from.map(|t| t.datetime()),
                &q.to.map(|t| t.datetime()),
                &q.before,
                &limit,
            ],
        )
        .await
        .map_err(map)?;
    found.iter().map(rows::summary).collect()
}

/// A sensor's calibrations within `from..=to`, oldest first.
pub async fn series(
    client: &Object,
    sensor_id: &str,
    from: Option<Timestamp>,
    to: Option<Timestamp>,
) -> Result<Vec<CalibrationSummary>, StoreError> {
    let sql = format!(
        "SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.sensor_id = $1 \
         AND ($2::timestamptz IS NULL OR c.performed_at >= $2) \
         AND ($3::timestamptz IS NULL OR c.performed_at <= $3) \
         ORDER BY c.performed_at, c.id"
    );
    let stmt = client.prepare_cached(&sql).await.map_err(map)?;
    let found = client
        .query(
            &stmt,
            &[
                &sensor_id,
                &from.map(|t| t.datetime()),
                &to.map(|t| t.datetime()),
            ],
        )
        .await
        .map_err(map)?;
    found.iter().map(rows::summary).collect()
}

/// The latest calibration of a sensor performed strictly before `before`.
pub async fn previous(
    client: &Object,
    sensor_id: &str,
    before: Timestamp,
) -> Result<Option<CalibrationSummary>, StoreError> {
    let sql = format!(
        "SELECT {SUMMARY_COLUMNS} FROM calibrations c WHERE c.sensor_id = $1 AND c.performed_at < $2 \
         ORDER BY c.performed_at DESC, c.id DESC LIMIT 1"
    );
    let row = client
        .query_opt(&sql, &[&sensor_id, &before.datetime()])
        .await
        .map_err(map)?;
    row.as_ref().map(rows::summary).transpose()
}

/// Whole calibrations in id order after `after` (for copying a database).
pub async fn export(
    client: &Object,
    after: Option<Uuid>,
    limit: usize,
) -> Result<Vec<NewCalibration>, StoreError> {
    let sql = format!(
        "SELECT {RECORD_COLUMNS} FROM calibrations c WHERE ($1::uuid IS NULL OR c.id > $1) \
         ORDER BY c.id LIMIT $2"
    );
    let found = client
        .query(&sql, &[&after, &(limit as i64)])
        .await
        .map_err(map)?;
    found.iter().map(rows::record).collect()
}
