//! Holds placed as a calibration is stored: in the writer's transaction,
//! the nonconformities of the standards the calibration names are judged
//! ([`crate::domain::nonconformity::bearing`]); one that bears on it —
//! performed in its window, or with the standard out of service — and one
//! holding the calibration it supersedes, for a standard it still uses,
//! hold it: one `hold` signature citing them, and the calibration in each
//! one's list. SQLite's one writer orders this after or before every
//! nonconformity's own transaction, never beside it.

use rusqlite::{Connection, params};

use super::{audit, rows};
use crate::domain::nonconformity::{Nonconformity, hold_on_storing};
use crate::domain::review::State;
use crate::store::{NONCONFORMITY_COLUMNS, NewCalibration, StoreError, sensor_recompute};

/// The nonconformities recorded of any of `standard_ids`, oldest first.
pub(super) fn findings(
    conn: &Connection,
    standard_ids: &[String],
) -> Result<Vec<Nonconformity>, StoreError> {
    let ids =
        serde_json::to_string(standard_ids).map_err(|e| StoreError::Refused(e.to_string()))?;
    rows::all(
        conn,
        &format!(
            "SELECT {NONCONFORMITY_COLUMNS} FROM nonconformities \
             WHERE standard_id IN (SELECT value FROM json_each(?1)) ORDER BY found_at, id"
        ),
        [ids],
        rows::nonconformity,
    )
}

/// The nonconformities that hold calibration `id`.
pub(super) fn holding(conn: &Connection, id: &str) -> Result<Vec<Nonconformity>, StoreError> {
    let columns = NONCONFORMITY_COLUMNS
        .split(", ")
        .map(|c| format!("n.{c}"))
        .collect::<Vec<_>>()
        .join(", ");
    rows::all(
        conn,
        &format!(
            "SELECT {columns} FROM nonconformities n JOIN nonconformity_calibrations h \
             ON h.nonconformity_id = n.id WHERE h.calibration_id = ?1 ORDER BY n.found_at, n.id"
        ),
        [id],
        rows::nonconformity,
    )
}

/// Holds `n`, just stored, under every nonconformity of its standards that
/// bears on it and under those of `inherited` (holding the calibration it
/// supersedes) whose standard it still uses; nothing when none does.
/// `latest`: whether it is its sensor's latest, so served until held.
pub(super) fn place(
    conn: &Connection,
    n: &NewCalibration,
    inherited: &[Nonconformity],
    latest: bool,
) -> Result<(), StoreError> {
    if n.standards.is_empty() {
        return Ok(());
    }
    let ids: Vec<String> = n.standards.iter().map(|u| u.standard_id.clone()).collect();
    let found = findings(conn, &ids)?;
    let held = n.held_by(&found, inherited);
    if held.is_empty() {
        return Ok(());
    }
    let id = n.id.to_string();
    let seq: i64 = rows::first(
        conn,
        "SELECT coalesce(max(seq), 0) AS last FROM signatures WHERE calibration_id = ?1",
        [&id],
        |r| r.get::<_, i64>("last").map_err(super::errors::map),
    )?
    .unwrap_or(0);
    let seq = u32::try_from(seq + 1).map_err(|e| StoreError::corrupt("signatures", e))?;
    let signature = hold_on_storing(&held, seq, n.received_at);
    super::signatures::insert(conn, n.id, &signature)?;
    for nc in &held {
        rows::execute(
            conn,
            "INSERT INTO nonconformity_calibrations (nonconformity_id, calibration_id, \
             state_found) VALUES (?1, ?2, ?3)",
            params![nc.id.to_string(), id, State::Submitted.as_str()],
        )?;
    }
    let entry = crate::store::audit::held_on_storing(
        n.id,
        &signature,
        &held.iter().map(|nc| nc.id).collect::<Vec<_>>(),
    );
    let effect = crate::domain::events::Effect::held_on_storing(n.id, latest);
    audit::append(conn, crate::store::audit::with_effect(entry, effect))?;
    rows::execute(conn, &sensor_recompute("?1"), [&n.sensor_id])?;
    Ok(())
}
