//! Holds placed as a calibration is stored: in the storing transaction,
//! the nonconformities of the standards the calibration names are judged
//! ([`crate::domain::nonconformity::bearing`]); one that bears on it —
//! performed in its window, or with the standard out of service — and one
//! holding the calibration it supersedes, for a standard it still uses,
//! hold it: one `hold` signature citing them, and the calibration in each
//! one's list.
//!
//! Recording a nonconformity locks its standard's row (`FOR UPDATE`) before
//! it reads what it holds; storing a calibration locks the rows of the
//! standards it names (`FOR SHARE`) first of all, before any other lock of
//! its transaction — so the two apply one after the other (whichever locks
//! first), never beside each other, and take their locks in one order.

use deadpool_postgres::{GenericClient, Transaction};
use uuid::Uuid;

use super::errors::map;
use super::rows;
use crate::domain::audit::Event;
use crate::domain::nonconformity::{Nonconformity, hold_on_storing};
use crate::domain::review::State;
use crate::store::{NONCONFORMITY_COLUMNS, NewCalibration, StoreError, sensor_recompute};

/// Locks the rows of the standards `n` names, shared: the first statement
/// of a transaction storing it.
pub async fn lock(tx: &Transaction<'_>, n: &NewCalibration) -> Result<(), StoreError> {
    if n.standards.is_empty() {
        return Ok(());
    }
    let ids: Vec<&str> = n.standards.iter().map(|u| u.standard_id.as_str()).collect();
    tx.execute(
        "SELECT 1 FROM standards WHERE standard_id = ANY($1) ORDER BY standard_id FOR SHARE",
        &[&ids],
    )
    .await
    .map_err(map)?;
    Ok(())
}

/// The nonconformities recorded of any of `standard_ids`, oldest first.
pub async fn findings(
    client: &impl GenericClient,
    standard_ids: &[String],
) -> Result<Vec<Nonconformity>, StoreError> {
    client
        .query(
            &format!(
                "SELECT {NONCONFORMITY_COLUMNS} FROM nonconformities \
                 WHERE standard_id = ANY($1) ORDER BY found_at, id"
            ),
            &[&standard_ids],
        )
        .await
        .map_err(map)?
        .iter()
        .map(rows::nonconformity)
        .collect()
}

/// The nonconformities that hold calibration `id`.
pub async fn holding(tx: &Transaction<'_>, id: Uuid) -> Result<Vec<Nonconformity>, StoreError> {
    let columns = NONCONFORMITY_COLUMNS
        .split(", ")
        .map(|c| format!("n.{c}"))
        .collect::<Vec<_>>()
        .join(", ");
    tx.query(
        &format!(
            "SELECT {columns} FROM nonconformities n JOIN nonconformity_calibrations h \
             ON h.nonconformity_id = n.id WHERE h.calibration_id = $1 ORDER BY n.found_at, n.id"
        ),
        &[&id],
    )
    .await
    .map_err(map)?
    .iter()
    .map(rows::nonconformity)
    .collect()
}

/// Holds `n`, just written in `tx` (its standards locked by [`lock`]),
/// under every nonconformity of its standards that bears on it and under
/// those of `inherited` (holding the calibration it supersedes) whose
/// standard it still uses; answers the audit event to append, none when
/// nothing holds it. `latest`: whether `n` is its sensor's latest, so
/// served until held.
pub async fn place(
    tx: &Transaction<'_>,
    n: &NewCalibration,
    inherited: &[Nonconformity],
    latest: bool,
) -> Result<Vec<Event>, StoreError> {
    if n.standards.is_empty() {
        return Ok(Vec::new());
    }
    let ids: Vec<String> = n.standards.iter().map(|u| u.standard_id.clone()).collect();
    let found = findings(tx, &ids).await?;
    let held = n.held_by(&found, inherited);
    if held.is_empty() {
        return Ok(Vec::new());
    }
    let last: i32 = rows::get(
        &tx.query_one(
            "SELECT coalesce(max(seq), 0) AS last FROM signatures WHERE calibration_id = $1",
            &[&n.id],
        )
        .await
        .map_err(map)?,
        "last",
    )?;
    let seq = u32::try_from(last + 1).map_err(|e| StoreError::corrupt("signatures", e))?;
    let signature = hold_on_storing(&held, seq, n.received_at);
    super::signatures::insert(tx, n.id, &signature).await?;
    for nc in &held {
        tx.execute(
            "INSERT INTO nonconformity_calibrations (nonconformity_id, calibration_id, \
             state_found) VALUES ($1, $2, $3)",
            &[&nc.id, &n.id, &State::Submitted.as_str()],
        )
        .await
        .map_err(map)?;
    }
    tx.execute(&sensor_recompute("$1"), &[&n.sensor_id])
        .await
        .map_err(map)?;
    let entry = crate::store::audit::held_on_storing(
        n.id,
        &signature,
        &held.iter().map(|nc| nc.id).collect::<Vec<_>>(),
    );
    let effect = crate::domain::events::Effect::held_on_storing(n.id, latest);
    Ok(vec![crate::store::audit::with_effect(entry, effect)])
}
