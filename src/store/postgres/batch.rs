//! A batch of calibrations written with one statement per table.
//!
//! The [`writer`](super::writer)'s transaction used to run
//! [`calibrations::write`](super::calibrations::write) for each calibration:
//! two or four statements each, every one a Bind, an Execute and a Sync that
//! PostgreSQL plans, runs, answers and flushes on its own. Here a batch of
//! `n` calibrations is at most four statements, whatever `n`:
//!
//! 1. the idempotency keys of the batch, looked at under their row locks
//!    (`FOR UPDATE`) in one `SELECT`; a key already completed is the answer
//!    of its write ([`Stored::Existing`]), which writes nothing;
//! 2. the calibrations still to write, inserted from arrays (`unnest`);
//! 3. their keys completed, guarded as one at a time is
//!    (`… WHERE idempotency_keys.calibration_id IS NULL`);
//! 4. one upsert per sensor, of the batch's writes of that sensor folded in
//!    the batch's order (see [`fold`]).
//!
//! What is stored is what the writes one after the other would have stored:
//! a sensor's summary is `count`, the least `performed_at`, the latest
//! calibration by `(performed_at, id)` with its verdict and due date, and
//! the last type a write assigned — each an associative fold, so folding
//! the batch first and then applying the fold to the stored row is the same
//! as applying each write in turn. A key named twice in one batch, or
//! completed by another request between the look and the completion, ends
//! the batch as [`Outcome::Raced`]: the writer rolls it back and stores each
//! write alone, where those cases are decided one at a time.

use std::collections::{BTreeMap, HashMap, HashSet};

use deadpool_postgres::Transaction;
use time::OffsetDateTime;
use uuid::Uuid;

use super::calibrations::Row;
use super::errors::map;
use super::rows;
use crate::store::{IdempotencyKey, SENSOR_MERGE, StoreError, Stored};

/// What writing a batch inside an open transaction came to.
#[derive(Debug)]
pub enum Outcome {
    /// Each write's answer, in the batch's order (stored once the
    /// transaction commits), and the sensors whose rows changed.
    Stored(Vec<Stored>, Option<Changed>),
    /// A key was named twice, or completed by another request meanwhile:
    /// the transaction must be rolled back.
    Raced,
}

/// The sensors a batch changed, and the backend process that changed them:
/// what its commit will notify ([`super::listen::Echoes`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Changed {
    /// The backend process id of the transaction's connection.
    pub pid: i32,
    /// The sensors upserted, each once.
    pub sensors: Vec<String>,
}

/// One sensor's summary of the batch's writes of it, in the batch's order.
#[derive(Debug, Clone, PartialEq)]
pub struct Fold<'a> {
    /// How many.
    pub count: i64,
    /// The least `performed_at`.
    pub first: OffsetDateTime,
    /// The latest by `(performed_at, id)`.
    pub latest: (OffsetDateTime, Uuid),
    /// The latest one's verdict.
    pub verdict: Option<&'a str>,
    /// The latest one's due date.
    pub due_at: Option<OffsetDateTime>,
    /// The last type a write assigned, if any did.
    pub assigned: Option<&'a str>,
}

/// Folds `rows` (in the batch's order) into one summary per sensor.
///
/// For sensor `s` with writes `w₁ … wₖ` of it, in order:
/// `count = k`, `first = min performed_at`,
/// `latest = max (performed_at, id)` (with that write's verdict and due
/// date), `assigned = the last non-null assigned type`.
pub fn fold<'a>(rows: impl IntoIterator<Item = &'a Row>) -> BTreeMap<&'a str, Fold<'a>> {
    let mut out: BTreeMap<&str, Fold> = BTreeMap::new();
    for row in rows {
        let n = row.new_calibration();
        let at = n.performed_at.datetime();
        let verdict = n.verdict.map(|v| v.as_str());
        let due_at = n.due_at.map(|t| t.datetime());
        let assigned = n.sensor_type.as_deref().filter(|_| n.assigns_type);
        match out.get_mut(n.sensor_id.as_str()) {
            None => {
                out.insert(
                    &n.sensor_id,
                    Fold {
                        count: 1,
                        first: at,
                        latest: (at, n.id),
                        verdict,
                        due_at,
                        assigned,
                    },
                );
            }
            Some(f) => {
                f.count += 1;
                f.first = f.first.min(at);
                if (at, n.id) > f.latest {
                    f.latest = (at, n.id);
                    f.verdict = verdict;
                    f.due_at = due_at;
                }
                if assigned.is_some() {
                    f.assigned = assigned;
                }
            }
        }
    }
    out
}

/// Writes `batch` (calibration, key) in `tx`; see the module's steps.
pub async fn write(
    tx: &Transaction<'_>,
    batch: &[(&Row, Option<&IdempotencyKey>)],
) -> Result<Outcome, StoreError> {
    let mut answers: Vec<Option<Stored>> = vec![None; batch.len()];

    // 1. The keys, each named once, looked at under their row locks.
    let keys: Vec<&IdempotencyKey> = batch.iter().filter_map(|(_, k)| *k).collect();
    let mut seen = HashSet::with_capacity(keys.len());
    if !keys.iter().all(|k| seen.insert((&k.principal, &k.key))) {
        return Ok(Outcome::Raced);
    }
    if !keys.is_empty() {
        let look = tx
            .prepare_cached(
                "SELECT k.principal, k.key, k.calibration_id FROM idempotency_keys k \
                 JOIN unnest($1::text[], $2::text[]) AS u(principal, key) \
                   ON k.principal = u.principal AND k.key = u.key \
                 FOR UPDATE OF k",
            )
            .await
            .map_err(map)?;
        let principals: Vec<&str> = keys.iter().map(|k| k.principal.as_str()).collect();
        let names: Vec<&str> = keys.iter().map(|k| k.key.as_str()).collect();
        let mut completed = HashMap::new();
        for found in tx.query(&look, &[&principals, &names]).await.map_err(map)? {
            if let Some(id) = rows::get::<Option<Uuid>>(&found, "calibration_id")? {
                let principal: String = rows::get(&found, "principal")?;
                let key: String = rows::get(&found, "key")?;
                completed.insert((principal, key), id);
            }
        }
        for ((_, key), answer) in batch.iter().zip(answers.iter_mut()) {
            if let Some(k) = key
                && let Some(id) = completed.get(&(k.principal.clone(), k.key.clone()))
            {
                *answer = Some(Stored::Existing(*id));
            }
        }
    }
    let to_write: Vec<(&Row, Option<&IdempotencyKey>)> = batch
        .iter()
        .zip(&answers)
        .filter(|(_, a)| a.is_none())
        .map(|(w, _)| *w)
        .collect();
    let answers = answers
        .into_iter()
        .map(|a| a.unwrap_or(Stored::New))
        .collect();
    if to_write.is_empty() {
        return Ok(Outcome::Stored(answers, None));
    }

    // 2. The calibrations.
    let rows: Vec<&Row> = to_write.iter().map(|(r, _)| *r).collect();
    insert_calibrations(tx, &rows).await?;

    // 3. Their keys, completed only where no one completed them meanwhile.
    let done: Vec<(&Row, &IdempotencyKey)> = to_write
        .iter()
        .filter_map(|(r, k)| k.map(|k| (*r, k)))
        .collect();
    if !done.is_empty() && complete_keys(tx, &done).await? != done.len() as u64 {
        return Ok(Outcome::Raced);
    }

    // 4. The sensors' summaries.
    let folds = fold(rows);
    let pid = upsert_sensors(tx, &folds).await?;
    let sensors = folds.keys().map(|s| (*s).to_owned()).collect();
    Ok(Outcome::Stored(answers, Some(Changed { pid, sensors })))
}

async fn insert_calibrations<'a>(tx: &Transaction<'_>, rows: &[&'a Row]) -> Result<(), StoreError> {
    let insert = tx
        .prepare_cached(
            "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, \
             model, runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
             sensor_type, verdict, due_at, expanded) \
             SELECT u.id, u.sensor_id, u.station_id, u.performed_at, u.received_at, u.unit, \
             u.model::json, u.runs, u.coefficients::json, u.std_errors::json, u.result, \
             u.submission, u.content_type, u.submitted_by, u.sensor_type, u.verdict, u.due_at, \
             u.expanded::json \
             FROM unnest($1::uuid[], $2::text[], $3::text[], $4::timestamptz[], \
               $5::timestamptz[], $6::text[], $7::text[], $8::int4[], $9::text[], $10::text[], \
               $11::text[], $12::bytea[], $13::text[], $14::text[], $15::text[], $16::text[], \
               $17::timestamptz[], $18::text[]) \
             AS u(id, sensor_id, station_id, performed_at, received_at, unit, model, runs, \
               coefficients, std_errors, result, submission, content_type, submitted_by, \
               sensor_type, verdict, due_at, expanded)",
        )
        .await
        .map_err(map)?;
    let n = |r: &&'a Row| r.new_calibration();
    let ids: Vec<Uuid> = rows.iter().map(|r| n(r).id).collect();
    let sensors: Vec<&str> = rows.iter().map(|r| n(r).sensor_id.as_str()).collect();
    let stations: Vec<Option<&str>> = rows.iter().map(|r| n(r).station_id.as_deref()).collect();
    let performed: Vec<OffsetDateTime> =
        rows.iter().map(|r| n(r).performed_at.datetime()).collect();
    let received: Vec<OffsetDateTime> = rows.iter().map(|r| n(r).received_at.datetime()).collect();
    let units: Vec<&str> = rows.iter().map(|r| n(r).unit.as_str()).collect();
    let models: Vec<&str> = rows.iter().map(|r| r.model()).collect();
    let runs: Vec<i32> = rows.iter().map(|r| r.runs()).collect();
    let coefficients: Vec<&str> = rows.iter().map(|r| r.coefficients()).collect();
    let std_errors: Vec<&str> = rows.iter().map(|r| r.std_errors()).collect();
    let results: Vec<&str> = rows.iter().map(|r| r.result()).collect::<Result<_, _>>()?;
    let submissions: Vec<&[u8]> = rows.iter().map(|r| &n(r).submission[..]).collect();
    let content_types: Vec<&str> = rows.iter().map(|r| n(r).content_type.as_str()).collect();
    let submitted_by: Vec<&str> = rows.iter().map(|r| n(r).submitted_by.as_str()).collect();
    let types: Vec<Option<&str>> = rows.iter().map(|r| n(r).sensor_type.as_deref()).collect();
    let verdicts: Vec<Option<&str>> = rows
        .iter()
        .map(|r| n(r).verdict.map(|v| v.as_str()))
        .collect();
    let due: Vec<Option<OffsetDateTime>> = rows
        .iter()
        .map(|r| n(r).due_at.map(|t| t.datetime()))
        .collect();
    let expanded: Vec<Option<&str>> = rows.iter().map(|r| r.expanded()).collect();
    tx.execute(
        &insert,
        &[
            &ids,
            &sensors,
            &stations,
            &performed,
            &received,
            &units,
            &models,
            &runs,
            &coefficients,
            &std_errors,
            &results,
            &submissions,
            &content_types,
            &submitted_by,
            &types,
            &verdicts,
            &due,
            &expanded,
        ],
    )
    .await
    .map_err(map)?;
    Ok(())
}

/// Completes `done`'s keys; returns how many it completed.
async fn complete_keys(
    tx: &Transaction<'_>,
    done: &[(&Row, &IdempotencyKey)],
) -> Result<u64, StoreError> {
    let complete = tx
        .prepare_cached(
            "INSERT INTO idempotency_keys (principal, key, request_hash, calibration_id, created_at) \
             SELECT * FROM unnest($1::text[], $2::text[], $3::bytea[], $4::uuid[], $5::timestamptz[]) \
             ON CONFLICT (principal, key) DO UPDATE SET calibration_id = excluded.calibration_id, \
               locked_until = NULL, holder = NULL WHERE idempotency_keys.calibration_id IS NULL",
        )
        .await
        .map_err(map)?;
    let principals: Vec<&str> = done.iter().map(|(_, k)| k.principal.as_str()).collect();
    let keys: Vec<&str> = done.iter().map(|(_, k)| k.key.as_str()).collect();
    let hashes: Vec<&[u8]> = done.iter().map(|(_, k)| &k.request_hash[..]).collect();
    let ids: Vec<Uuid> = done.iter().map(|(r, _)| r.new_calibration().id).collect();
    let at: Vec<OffsetDateTime> = done
        .iter()
        .map(|(r, _)| r.new_calibration().received_at.datetime())
        .collect();
    tx.execute(&complete, &[&principals, &keys, &hashes, &ids, &at])
        .await
        .map_err(map)
}

/// Applies each sensor's fold to its stored summary (or creates it), by
/// the rules of one write's upsert ([`SENSOR_MERGE`]); answers the
/// connection's backend process id.
async fn upsert_sensors(
    tx: &Transaction<'_>,
    folds: &BTreeMap<&str, Fold<'_>>,
) -> Result<i32, StoreError> {
    let upsert = tx
        .prepare_cached(&format!(
            "INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
             latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at) \
             SELECT * FROM unnest($1::text[], $2::int8[], $3::timestamptz[], $4::timestamptz[], \
               $5::uuid[], $6::text[], $7::text[], $8::timestamptz[]) {SENSOR_MERGE} \
             RETURNING pg_backend_pid() AS pid"
        ))
        .await
        .map_err(map)?;
    // In sensor order (the map's), so that two replicas' batches take the
    // sensors' row locks in one order.
    let sensors: Vec<&str> = folds.keys().copied().collect();
    let counts: Vec<i64> = folds.values().map(|f| f.count).collect();
    let first: Vec<OffsetDateTime> = folds.values().map(|f| f.first).collect();
    let latest_at: Vec<OffsetDateTime> = folds.values().map(|f| f.latest.0).collect();
    let latest_id: Vec<Uuid> = folds.values().map(|f| f.latest.1).collect();
    let types: Vec<Option<&str>> = folds.values().map(|f| f.assigned).collect();
    let verdicts: Vec<Option<&str>> = folds.values().map(|f| f.verdict).collect();
    let due: Vec<Option<OffsetDateTime>> = folds.values().map(|f| f.due_at).collect();
    let upserted = tx
        .query(
            &upsert,
            &[
                &sensors, &counts, &first, &latest_at, &latest_id, &types, &verdicts, &due,
            ],
        )
        .await
        .map_err(map)?;
    match upserted.first() {
        Some(row) => rows::get(row, "pid"),
        None => Err(StoreError::corrupt(
            "the sensors' upsert",
            "it answered no row",
        )),
    }
}
