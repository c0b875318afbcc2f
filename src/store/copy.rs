//! Copying one database into another (`accelcal migrate`): SQLite to
//! PostgreSQL when a deployment outgrows one machine, or any engine to any.
//!
//! Everything a running service needs comes across: every sensor type,
//! standard, customer and item, every token (its hash; revoked ones stay revoked), every calibration with its
//! result and submission byte for byte and its signatures (replayed in order,
//! through the same checks) and issued certificates (every revision, byte for
//! byte), every nonconformity of a standard with the
//! calibrations of its window, the sensors' assigned types, and the
//! completed idempotency keys still within their retention (so a station's
//! retry after the move is still answered with its calibration). Sensor
//! summaries are rebuilt by the same inserts that built them. Web sessions
//! and in-flight leases are not copied: people sign in again, and a request
//! in flight at the move had its process stopped. Nor is the audit trail:
//! the target's own chain records the copy (each calibration and signature
//! by its original actor, every other row by the operator who ran the
//! command), and the source keeps its chain, `accelcal audit verify`-able.
//!
//! **Interrupted, resumed, never silent.** The target is marked as being
//! imported into before the first row is copied, and the mark is removed
//! only after the last: a service refuses to start on a marked database
//! ([`refuse_unfinished`]), so a migrate killed half-way is never served as
//! complete. Running the same migrate again resumes: it skips every row the
//! target already holds *identically* and copies the rest. A row the target
//! holds differently — a sensor type, token, calibration, sensor's type or
//! idempotency key of the same id with other content — stops the copy with
//! [`CopyError::Conflict`] naming it: nothing is overwritten.

use serde::Serialize;

use super::Precondition;
use super::{DoneKey, IDEMPOTENCY_RETENTION_SECONDS, SensorQuery, Signed, Store, StoreError};
use crate::domain::audit::Actor;
use crate::domain::auth::Principal;
use crate::domain::review::Act;
use crate::domain::timestamp::Timestamp;

/// Calibrations read and written per round trip.
const PAGE: usize = 200;

/// What was copied.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Copied {
    /// Sensor types.
    pub sensor_types: usize,
    /// Reference standards.
    pub standards: usize,
    /// Customers.
    pub customers: usize,
    /// Items behind sensor ids.
    pub items: usize,
    /// Tokens.
    pub tokens: usize,
    /// Calibrations.
    pub calibrations: usize,
    /// Signatures on them (approvals, rejections, withdrawals).
    pub signatures: usize,
    /// Revisions of issued certificates.
    pub certificates: usize,
    /// Nonconformities of standards, with the calibrations of their
    /// windows.
    pub nonconformities: usize,
    /// Sensors given their assigned type.
    pub typed_sensors: usize,
    /// Completed idempotency keys.
    pub idempotency_keys: usize,
    /// Rows the target already held identically (a resumed copy).
    pub already_there: usize,
}

/// Why a copy did not happen.
#[derive(Debug, thiserror::Error)]
pub enum CopyError {
    /// The target already holds data and adding to it was not asked for.
    #[error(
        "the target database is not empty; copy into an empty database, or pass --into-non-empty to add to it"
    )]
    NotEmpty,
    /// The target holds a row of the same id with other content.
    #[error(
        "the target already holds {0} with other content; nothing of it was overwritten \
         (the copy stopped there: resolve it, then run the same migrate again to resume)"
    )]
    Conflict(String),
    /// A database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Refuses (with what to do) a database an `accelcal migrate` did not finish
/// copying into: the service must not serve part of a database as the whole.
pub async fn refuse_unfinished(store: &dyn Store) -> anyhow::Result<()> {
    if let Some(what) = store.import_in_progress().await? {
        anyhow::bail!(
            "this database is the target of an `accelcal migrate` that did not finish ({what}); \
             run the same migrate again to finish it (it resumes where it stopped)"
        );
    }
    Ok(())
}

/// Whether `existing` (the target's row, if any) is `wanted`: `Ok(true)` to
/// skip it, `Ok(false)` to copy it, a conflict when it differs.
fn present<T: PartialEq>(
    existing: Option<T>,
    wanted: &T,
    what: impl FnOnce() -> String,
) -> Result<bool, CopyError> {
    match existing {
        None => Ok(false),
        Some(e) if e == *wanted => Ok(true),
        Some(_) => Err(CopyError::Conflict(what())),
    }
}

/// Replays onto the target the signatures of calibration `id` it does not
/// hold yet, in order, each through the same checks that admitted it
/// ([`crate::domain::review::Act::check`]) and compared with the source's
/// once recorded; how many were copied.
async fn copy_signatures(
    from: &dyn Store,
    to: &dyn Store,
    id: uuid::Uuid,
) -> Result<usize, CopyError> {
    let wanted = from.signatures(id).await?;
    let there = to.signatures(id).await?;
    let conflict = || CopyError::Conflict(format!("calibration `{id}`'s signatures"));
    if there.len() > wanted.len() || wanted[..there.len()] != there[..] {
        return Err(conflict());
    }
    for s in &wanted[there.len()..] {
        let act = Act {
            action: s.action,
            signer: Principal {
                id: s.token_id.clone(),
                role: s.role,
                station_id: None,
                holder: s.holder.clone(),
            },
            at: s.signed_at,
            comment: s.comment.clone(),
            superseded_by: s.superseded_by,
        };
        match to.sign(id, act).await? {
            Signed::Done(copy, _) if copy == *s => {}
            _ => return Err(conflict()),
        }
    }
    Ok(wanted.len() - there.len())
}

/// Copies onto the target the revisions of calibration `id`'s issued
/// certificate it does not hold yet, as they were issued (the documents byte
/// for byte); how many were copied.
async fn copy_certificates(
    from: &dyn Store,
    to: &dyn Store,
    id: uuid::Uuid,
) -> Result<usize, CopyError> {
    let wanted = from.revisions(id).await?;
    let there = to.revisions(id).await?;
    let conflict = || CopyError::Conflict(format!("calibration `{id}`'s certificate"));
    if there.len() > wanted.len() || wanted[..there.len()] != there[..] {
        return Err(conflict());
    }
    for r in &wanted[there.len()..] {
        let c = from
            .certificate(id, Some(r.revision))
            .await?
            .ok_or_else(conflict)?;
        if !to.issue_certificate(c).await? {
            return Err(conflict());
        }
    }
    Ok(wanted.len() - there.len())
}

/// Copies everything from `from` (described as `source`) into `to` (which
/// must be empty unless `into_non_empty`, or the target of an unfinished
/// copy), as of `now`.
pub async fn copy(
    from: &dyn Store,
    source: &str,
    to: &dyn Store,
    into_non_empty: bool,
    now: Timestamp,
) -> Result<Copied, CopyError> {
    let resuming = to.import_in_progress().await?.is_some();
    if !resuming && !into_non_empty && !to.is_empty().await? {
        return Err(CopyError::NotEmpty);
    }
    to.set_import_in_progress(Some(format!("from {source}, started {now}")))
        .await?;
    let mut copied = Copied::default();
    for t in from.sensor_types().await? {
        let existing = to.sensor_type(t.type_id.clone()).await?;
        if present(existing, &t, || format!("sensor type `{}`", t.type_id))? {
            copied.already_there += 1;
            continue;
        }
        to.put_sensor_type(t, Actor::command_line(), Precondition::Any)
            .await?;
        copied.sensor_types += 1;
    }
    for s in from.standards().await? {
        let existing = to.standard(s.standard_id.clone()).await?;
        if present(existing, &s, || format!("standard `{}`", s.standard_id))? {
            copied.already_there += 1;
            continue;
        }
        to.put_standard(s, Actor::command_line(), Precondition::Any)
            .await?;
        copied.standards += 1;
    }
    for c in from.customers().await? {
        let existing = to.customer(c.customer_id.clone()).await?;
        if present(existing, &c, || format!("customer `{}`", c.customer_id))? {
            copied.already_there += 1;
            continue;
        }
        to.put_customer(c, Actor::command_line(), Precondition::Any)
            .await?;
        copied.customers += 1;
    }
    for i in from.items().await? {
        let existing = to.item(i.sensor_id.clone()).await?;
        if present(existing, &i, || format!("sensor `{}`'s item", i.sensor_id))? {
            copied.already_there += 1;
            continue;
        }
        to.put_item(i, Actor::command_line(), Precondition::Any)
            .await?;
        copied.items += 1;
    }
    for t in from.tokens().await? {
        let existing = to.token(t.id).await?;
        if present(existing, &t, || format!("token `{}`", t.id))? {
            copied.already_there += 1;
            continue;
        }
        to.insert_token(t, Actor::command_line()).await?;
        copied.tokens += 1;
    }
    let mut after = None;
    loop {
        let page = from.export_calibrations(after, PAGE).await?;
        let Some(last) = page.last() else { break };
        after = Some(last.id);
        for c in page {
            let id = c.id;
            let existing = to.calibration_result(id).await?;
            if present(existing, &c.result, || format!("calibration `{id}`"))? {
                copied.already_there += 1;
            } else {
                to.insert_calibration(c, None).await?;
                copied.calibrations += 1;
            }
            copied.signatures += copy_signatures(from, to, id).await?;
            copied.certificates += copy_certificates(from, to, id).await?;
        }
    }
    for standard in from.standards().await? {
        let there = to.nonconformities(standard.standard_id.clone()).await?;
        for t in from.nonconformities(standard.standard_id.clone()).await? {
            let id = t.nonconformity.id;
            let existing = there.iter().find(|x| x.nonconformity.id == id);
            // What became of its calibrations is theirs (their signatures,
            // copied above); the record is what it was when recorded.
            let record = |x: &crate::domain::nonconformity::Traced| {
                let found: Vec<_> = x
                    .calibrations
                    .iter()
                    .map(|c| (c.calibration_id, c.state_found))
                    .collect();
                (x.nonconformity.clone(), found)
            };
            if let Some(x) = existing {
                if record(x) != record(&t) {
                    return Err(CopyError::Conflict(format!("nonconformity `{id}`")));
                }
                copied.already_there += 1;
                continue;
            }
            to.put_nonconformity(t).await?;
            copied.nonconformities += 1;
        }
    }
    let mut after = None;
    loop {
        let page = from
            .sensors(SensorQuery {
                after: after.clone(),
                status: None,
                search: None,
                now,
                limit: PAGE,
            })
            .await?;
        let Some(last) = page.last() else { break };
        after = Some(last.sensor_id.clone());
        for s in page {
            let Some(t) = s.sensor_type else { continue };
            let existing = to
                .sensor(s.sensor_id.clone(), now)
                .await?
                .and_then(|there| there.sensor_type);
            if present(existing, &t, || format!("sensor `{}`'s type", s.sensor_id))? {
                copied.already_there += 1;
                continue;
            }
            to.assign_sensor_type(s.sensor_id, t, Actor::command_line())
                .await?;
            copied.typed_sensors += 1;
        }
    }
    let since = now.plus_seconds(-IDEMPOTENCY_RETENTION_SECONDS);
    let there: std::collections::HashMap<(String, String), DoneKey> = to
        .done_keys(since)
        .await?
        .into_iter()
        .map(|k| ((k.principal.clone(), k.key.clone()), k))
        .collect();
    for k in from.done_keys(since).await? {
        let existing = there.get(&(k.principal.clone(), k.key.clone())).cloned();
        if present(existing, &k, || format!("idempotency key `{}`", k.key))? {
            copied.already_there += 1;
            continue;
        }
        to.put_done_key(k).await?;
        copied.idempotency_keys += 1;
    }
    to.set_import_in_progress(None).await?;
    Ok(copied)
}
