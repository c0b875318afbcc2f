//! A batch of calibrations written with one statement per table.
//!
//! The [`writer`](super::writer)'s transaction used to run
//! [`calibrations::write`](super::calibrations::write) for each calibration:
//! two or four statements each, every one a Bind, an Execute and a Sync that
//! PostgreSQL plans, runs, answers and flushes on its own. Here a batch of
//! `n` calibrations is at most four statements, whatever `n`, and its audit
//! entries:
//!
//! 1. the idempotency keys of the batch, looked at under their row locks
//!    (`FOR UPDATE`) in one `SELECT`; a key already completed is the answer
//!    of its write ([`Stored::Existing`]), which writes nothing;
//! 2. the calibrations still to write, inserted from arrays (`unnest`),
//!    their submitters' tokens read first;
//! 3. their keys completed, guarded as one at a time is
//!    (`… WHERE idempotency_keys.calibration_id IS NULL`);
//! 4. one upsert of every sensor the batch wrote, each with the batch's
//!    calibrations of it aggregated in SQL ([`UPSERT_SENSORS`]) and merged
//!    into its row by [`SENSOR_MERGE`], answering the rows;
//! 5. their `calibration.submitted` entries appended to the audit trail,
//!    built from what each request prepared ([`crate::store::audit::Submitted`]):
//!    between the upsert, which holds the sensors' rows against other
//!    replicas' batches, and the commit there is one statement and no digest.
//!
//! What is stored is what the writes one after the other would have stored:
//! a sensor's summary is `count`, the least `performed_at`, the latest
//! calibration by `(performed_at, id)` with its verdict and due date, and
//! the last type a write assigned — each an associative fold, so folding
//! the batch first and then merging the fold into the stored row is the
//! same as merging each write in turn. A key named twice in one batch, or
//! completed by another request between the look and the completion, ends
//! the batch as [`Outcome::Raced`]: the writer rolls it back and stores each
//! write alone, where those cases are decided one at a time.

use std::collections::{HashMap, HashSet};
use std::sync::LazyLock;

use deadpool_postgres::Transaction;
use time::OffsetDateTime;
use uuid::Uuid;

use super::calibrations::Row;
use super::errors::map;
use super::rows;
use crate::store::{
    IdempotencyKey, NEWEST_FIRST, SENSOR_MERGE, SENSOR_ROW, SensorRow, StoreError, Stored,
};

/// What writing a batch inside an open transaction came to.
#[derive(Debug)]
pub enum Outcome {
    /// Each write's answer, in the batch's order (stored once the
    /// transaction commits) with its sensor's row as the batch left it,
    /// and the sensors whose rows changed.
    Stored(Vec<(Stored, Option<SensorRow>)>, Option<Changed>),
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

/// The batch's calibrations (`$1`, in the batch's order, each with the
/// type it assigns, `$2`) aggregated per sensor — the count, the least
/// `performed_at`, the latest by [`NEWEST_FIRST`] with its verdict and due
/// date, the last type assigned — and merged into the sensors' rows, in
/// sensor order (so that two replicas' batches take the rows' locks in one
/// order); answers the rows and the connection's backend process.
static UPSERT_SENSORS: LazyLock<String> = LazyLock::new(|| {
    let latest = |column: &str| format!("(array_agg(c.{column} {NEWEST_FIRST}))[1]");
    format!(
        "INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
         latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at) \
         SELECT c.sensor_id, count(*), min(c.performed_at), {}, {}, \
           (array_agg(w.assigned ORDER BY w.position DESC) FILTER (WHERE w.assigned IS NOT NULL))[1], \
           {}, {} \
         FROM unnest($1::uuid[], $2::text[]) WITH ORDINALITY AS w(id, assigned, position) \
         JOIN calibrations c ON c.id = w.id \
         GROUP BY c.sensor_id ORDER BY c.sensor_id \
         {SENSOR_MERGE} {SENSOR_ROW}, pg_backend_pid() AS pid",
        latest("performed_at"),
        latest("id"),
        latest("verdict"),
        latest("due_at"),
    )
});

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
    if to_write.is_empty() {
        let answers = answers
            .into_iter()
            .map(|a| (a.unwrap_or(Stored::New), None));
        return Ok(Outcome::Stored(answers.collect(), None));
    }

    // 2. The calibrations; their submitters looked up first, so that
    // nothing but the audit entries' insert and the commit follows the
    // sensors' upsert (which holds their rows against other replicas).
    let rows: Vec<&Row> = to_write.iter().map(|(r, _)| *r).collect();
    let by: Vec<&str> = rows
        .iter()
        .map(|r| r.new_calibration().submitted_by.as_str())
        .collect();
    let actors = super::audit::submitters(tx, &by).await?;
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
    let (pid, merged) = upsert_sensors(tx, &rows).await?;

    // 5. Their entries for the audit trail (pending until sealed: super::seal).
    // A calibration is served once stored when it is its sensor's latest as
    // the batch leaves the row: no reader sees the rows between the batch's
    // writes, which commit as one.
    let written: Vec<super::audit::Written> = rows
        .iter()
        .map(|r| {
            let n = r.new_calibration();
            let latest = merged
                .get(r.sensor_id())
                .is_some_and(|s| s.latest_calibration_id == n.id);
            (n, r.entry(), latest)
        })
        .collect();
    super::audit::append(tx, super::audit::entries(&actors, &written)?).await?;
    let answers = batch
        .iter()
        .zip(answers)
        .map(|((row, _), a)| match a {
            Some(existing) => (existing, None),
            None => (Stored::New, merged.get(row.sensor_id()).cloned()),
        })
        .collect();
    let sensors = merged.into_keys().collect();
    Ok(Outcome::Stored(answers, Some(Changed { pid, sensors })))
}

async fn insert_calibrations<'a>(tx: &Transaction<'_>, rows: &[&'a Row]) -> Result<(), StoreError> {
    let insert = tx
        .prepare_cached(
            "INSERT INTO calibrations (id, sensor_id, station_id, performed_at, received_at, unit, \
             model, runs, coefficients, std_errors, result, submission, content_type, submitted_by, \
             sensor_type, verdict, due_at, expanded, triad, thermal) \
             SELECT u.id, u.sensor_id, u.station_id, u.performed_at, u.received_at, u.unit, \
             u.model::json, u.runs, u.coefficients::json, u.std_errors::json, u.result, \
             u.submission, u.content_type, u.submitted_by, u.sensor_type, u.verdict, u.due_at, \
             u.expanded::json, u.triad::json, u.thermal::json \
             FROM unnest($1::uuid[], $2::text[], $3::text[], $4::timestamptz[], \
               $5::timestamptz[], $6::text[], $7::text[], $8::int4[], $9::text[], $10::text[], \
               $11::text[], $12::bytea[], $13::text[], $14::text[], $15::text[], $16::text[], \
               $17::timestamptz[], $18::text[], $19::text[], $20::text[]) \
             AS u(id, sensor_id, station_id, performed_at, received_at, unit, model, runs, \
               coefficients, std_errors, result, submission, content_type, submitted_by, \
               sensor_type, verdict, due_at, expanded, triad, thermal)",
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
    let triads: Vec<Option<&str>> = rows.iter().map(|r| r.triad()).collect();
    let thermals: Vec<Option<&str>> = rows.iter().map(|r| r.thermal()).collect();
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
            &triads,
            &thermals,
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

/// Merges the batch's calibrations `rows` (in the batch's order) into
/// their sensors' rows ([`UPSERT_SENSORS`]); answers the connection's
/// backend process id and each sensor's row as it left it.
async fn upsert_sensors(
    tx: &Transaction<'_>,
    rows: &[&Row],
) -> Result<(i32, HashMap<String, SensorRow>), StoreError> {
    let upsert = tx.prepare_cached(&UPSERT_SENSORS).await.map_err(map)?;
    let ids: Vec<Uuid> = rows.iter().map(|r| r.new_calibration().id).collect();
    let assigned: Vec<Option<&str>> = rows
        .iter()
        .map(|r| {
            let n = r.new_calibration();
            n.sensor_type.as_deref().filter(|_| n.assigns_type)
        })
        .collect();
    let upserted = tx.query(&upsert, &[&ids, &assigned]).await.map_err(map)?;
    let pid = match upserted.first() {
        Some(row) => rows::get(row, "pid")?,
        None => {
            return Err(StoreError::corrupt(
                "the sensors' upsert",
                "it answered no row",
            ));
        }
    };
    let merged = upserted
        .iter()
        .map(|r| rows::sensor_row(r).map(|s| (s.sensor_id.clone(), s)))
        .collect::<Result<_, _>>()?;
    Ok((pid, merged))
}
