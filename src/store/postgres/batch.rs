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
//!    calibrations of it folded here ([`fold`]) and merged into its row by
//!    [`SENSOR_MERGE`] ([`UPSERT_SENSORS`]), answering the rows;
//! 5. in the same statement, their `calibration.submitted` entries appended
//!    to the audit trail, built from what each request prepared
//!    ([`crate::store::audit::Submitted`]): between the upsert, which holds
//!    the sensors' rows against other replicas' batches, and the commit
//!    there is no round trip and no digest.
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

use std::collections::btree_map::Entry;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::LazyLock;

use deadpool_postgres::Transaction;
use time::OffsetDateTime;
use uuid::Uuid;

use super::calibrations::Row;
use super::errors::map;
use super::rows;
use crate::domain::audit::Actor;
use crate::domain::events::Effect;
use crate::store::audit::SUBMITTED;
use crate::store::{IdempotencyKey, SENSOR_MERGE, SENSOR_ROW, SensorRow, StoreError, Stored};

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

/// The batch's calibrations folded per sensor ([`fold`]: `$1`…`$8`, one
/// element per sensor) merged into the sensors' rows in sensor order (so
/// that two replicas' batches take the rows' locks in one order), and in
/// the same statement their `calibration.submitted` entries (`$9`…`$18`,
/// one per calibration, in the batch's order) appended to `audit_pending`,
/// each with the effect its sensor's row as merged gives it: `$17`, served,
/// when it became the latest, `$19`, unchanged, when not. One statement,
/// so that between taking the rows' locks and the commit there is no round
/// trip to this process — which, on two shared cores, may be busy with
/// other requests when the database answers, while another replica's batch
/// waits for the rows. A `LEFT JOIN`, so that no entry can be dropped;
/// answers the rows and the connection's backend process.
static UPSERT_SENSORS: LazyLock<String> = LazyLock::new(|| {
    format!(
        "WITH s AS (INSERT INTO sensors (sensor_id, calibration_count, first_performed_at, \
           latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at) \
           SELECT * FROM unnest($1::text[], $2::int8[], $3::timestamptz[], $4::timestamptz[], \
             $5::uuid[], $6::text[], $7::text[], $8::timestamptz[]) \
             AS f(sensor_id, calibration_count, first_performed_at, latest_performed_at, \
               latest_calibration_id, sensor_type, latest_verdict, latest_due_at) \
           ORDER BY f.sensor_id COLLATE \"C\" \
           {SENSOR_MERGE} {SENSOR_ROW}), \
         a AS (INSERT INTO audit_pending (at, token_id, role, holder, action, object, change) \
           SELECT u.at, u.token_id, u.role, u.holder, $20, u.object, \
             u.head || CASE WHEN s.latest_calibration_id = u.id THEN u.served ELSE $19 END || u.tail \
           FROM unnest($9::uuid[], $10::text[], $11::timestamptz[], $12::text[], $13::text[], \
             $14::text[], $15::text[], $16::text[], $17::text[], $18::text[]) WITH ORDINALITY \
             AS u(id, sensor_id, at, token_id, role, holder, object, head, served, tail, n) \
           LEFT JOIN s ON s.sensor_id = u.sensor_id COLLATE \"C\" ORDER BY u.n) \
         SELECT s.*, pg_backend_pid() AS pid FROM s"
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
    // nothing but the commit follows the sensors' upsert (which holds
    // their rows against other replicas, and appends the entries).
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

    // 4 and 5. The sensors' summaries and the entries for the audit trail
    // (pending until sealed: super::seal), in one statement. A calibration
    // is served once stored when it is its sensor's latest as the batch
    // leaves the row: no reader sees the rows between the batch's writes,
    // which commit as one.
    let (pid, merged) = upsert_sensors(tx, &rows, &actors).await?;
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

/// The batch's calibrations `rows` (in the batch's order) folded per
/// sensor, in byte order of the sensor ids (PostgreSQL's `COLLATE "C"`):
/// each sensor's count, its least `performed_at`, its latest calibration
/// by `(performed_at, id)` ([`crate::store::NEWEST_FIRST`]; a uuid orders
/// by its bytes in both) with that one's verdict and due date, and the last
/// type a write assigned — the row the writes would leave for a sensor
/// that had none, which [`SENSOR_MERGE`] merges into a stored one as it
/// merges one write.
fn fold(rows: &[&Row]) -> Vec<SensorRow> {
    let mut by: BTreeMap<&str, SensorRow> = BTreeMap::new();
    for r in rows {
        let n = r.new_calibration();
        let assigned = n.sensor_type.as_deref().filter(|_| n.assigns_type);
        match by.entry(n.sensor_id.as_str()) {
            Entry::Vacant(v) => {
                v.insert(SensorRow {
                    sensor_id: n.sensor_id.clone(),
                    calibration_count: 1,
                    first_performed_at: n.performed_at,
                    latest_performed_at: n.performed_at,
                    latest_calibration_id: n.id,
                    sensor_type: assigned.map(str::to_owned),
                    latest_verdict: n.verdict,
                    due_at: n.due_at,
                });
            }
            Entry::Occupied(o) => {
                let s = o.into_mut();
                s.calibration_count += 1;
                s.first_performed_at = s.first_performed_at.min(n.performed_at);
                if (n.performed_at, n.id) > (s.latest_performed_at, s.latest_calibration_id) {
                    s.latest_performed_at = n.performed_at;
                    s.latest_calibration_id = n.id;
                    s.latest_verdict = n.verdict;
                    s.due_at = n.due_at;
                }
                if let Some(t) = assigned {
                    s.sensor_type = Some(t.to_owned());
                }
            }
        }
    }
    by.into_values().collect()
}

/// Merges the batch's calibrations `rows` (in the batch's order) into
/// their sensors' rows and appends their entries, by `actors`
/// ([`fold`], [`UPSERT_SENSORS`]); answers the connection's backend process
/// id and each sensor's row as it left it.
async fn upsert_sensors(
    tx: &Transaction<'_>,
    rows: &[&Row],
    actors: &HashMap<&str, Actor>,
) -> Result<(i32, HashMap<String, SensorRow>), StoreError> {
    let upsert = tx.prepare_cached(&UPSERT_SENSORS).await.map_err(map)?;
    let folded = fold(rows);
    let ids: Vec<&str> = folded.iter().map(|s| s.sensor_id.as_str()).collect();
    let counts: Vec<i64> = folded.iter().map(|s| s.calibration_count as i64).collect();
    let first: Vec<OffsetDateTime> = folded
        .iter()
        .map(|s| s.first_performed_at.datetime())
        .collect();
    let latest: Vec<OffsetDateTime> = folded
        .iter()
        .map(|s| s.latest_performed_at.datetime())
        .collect();
    let latest_ids: Vec<Uuid> = folded.iter().map(|s| s.latest_calibration_id).collect();
    let types: Vec<Option<&str>> = folded.iter().map(|s| s.sensor_type.as_deref()).collect();
    let verdicts: Vec<Option<&str>> = folded
        .iter()
        .map(|s| s.latest_verdict.map(|v| v.as_str()))
        .collect();
    let due: Vec<Option<OffsetDateTime>> = folded
        .iter()
        .map(|s| s.due_at.map(|t| t.datetime()))
        .collect();
    let e = Entries::of(rows, actors)?;
    let upserted = tx
        .query(
            &upsert,
            &[
                &ids,
                &counts,
                &first,
                &latest,
                &latest_ids,
                &types,
                &verdicts,
                &due,
                &e.ids,
                &e.sensors,
                &e.at,
                &e.token_ids,
                &e.roles,
                &e.holders,
                &e.objects,
                &e.heads,
                &e.served,
                &e.tails,
                &e.unchanged,
                &SUBMITTED,
            ],
        )
        .await
        .map_err(map)?;
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

/// The columns of a batch's `calibration.submitted` entries
/// ([`crate::store::audit::Submitted`]), one element per calibration: its
/// change as the text around the effect and the effect that serves it, the
/// effect that changes nothing being one text for all.
struct Entries<'a> {
    ids: Vec<Uuid>,
    sensors: Vec<&'a str>,
    at: Vec<OffsetDateTime>,
    token_ids: Vec<&'a str>,
    roles: Vec<&'a str>,
    holders: Vec<Option<&'a str>>,
    objects: Vec<String>,
    heads: Vec<&'a str>,
    served: Vec<String>,
    tails: Vec<&'a str>,
    unchanged: String,
}

impl<'a> Entries<'a> {
    fn of(rows: &[&'a Row], actors: &'a HashMap<&str, Actor>) -> Result<Self, StoreError> {
        let mut e = Entries {
            ids: Vec::with_capacity(rows.len()),
            sensors: Vec::with_capacity(rows.len()),
            at: Vec::with_capacity(rows.len()),
            token_ids: Vec::with_capacity(rows.len()),
            roles: Vec::with_capacity(rows.len()),
            holders: Vec::with_capacity(rows.len()),
            objects: Vec::with_capacity(rows.len()),
            heads: Vec::with_capacity(rows.len()),
            served: Vec::with_capacity(rows.len()),
            tails: Vec::with_capacity(rows.len()),
            unchanged: Effect::stored(Uuid::nil(), false).to_value().to_string(),
        };
        for r in rows {
            let n = r.new_calibration();
            let by = actors.get(n.submitted_by.as_str()).ok_or_else(|| {
                StoreError::corrupt("audit", "a submitter was not looked up before its entry")
            })?;
            let (head, tail) = r.entry().around_effect();
            e.ids.push(n.id);
            e.sensors.push(&n.sensor_id);
            e.at.push(r.entry().at().datetime());
            e.token_ids.push(&by.token_id);
            e.roles.push(&by.role);
            e.holders.push(by.holder.as_deref());
            e.objects.push(crate::domain::audit::calibration(n.id));
            e.heads.push(head);
            e.served
                .push(Effect::stored(n.id, true).to_value().to_string());
            e.tails.push(tail);
        }
        Ok(e)
    }
}
