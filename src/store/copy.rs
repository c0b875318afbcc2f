//! Copying one database into another (`accelcal migrate`): SQLite to
//! PostgreSQL when a deployment outgrows one machine, or any engine to any.
//!
//! Everything a running service needs comes across: every sensor type, every
//! token (its hash; revoked ones stay revoked), every calibration with its
//! result and submission byte for byte, the sensors' assigned types, and the
//! completed idempotency keys still within their retention (so a station's
//! retry after the move is still answered with its calibration). Sensor
//! summaries are rebuilt by the same inserts that built them. Web sessions
//! and in-flight leases are not copied: people sign in again, and a request
//! in flight at the move had its process stopped.

use serde::Serialize;

use super::{IDEMPOTENCY_RETENTION_SECONDS, SensorQuery, Store, StoreError};
use crate::domain::timestamp::Timestamp;

/// Calibrations read and written per round trip.
const PAGE: usize = 200;

/// What was copied.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Copied {
    /// Sensor types.
    pub sensor_types: usize,
    /// Tokens.
    pub tokens: usize,
    /// Calibrations.
    pub calibrations: usize,
    /// Sensors given their assigned type.
    pub typed_sensors: usize,
    /// Completed idempotency keys.
    pub idempotency_keys: usize,
}

/// Why a copy did not happen.
#[derive(Debug, thiserror::Error)]
pub enum CopyError {
    /// The target already holds data and adding to it was not asked for.
    #[error(
        "the target database is not empty; copy into an empty database, or pass --into-non-empty to add to it"
    )]
    NotEmpty,
    /// A database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Copies everything from `from` into `to` (which must be empty unless
/// `into_non_empty`), as of `now`.
pub async fn copy(
    from: &dyn Store,
    to: &dyn Store,
    into_non_empty: bool,
    now: Timestamp,
) -> Result<Copied, CopyError> {
    if !into_non_empty && !to.is_empty().await? {
        return Err(CopyError::NotEmpty);
    }
    let mut copied = Copied::default();
    for t in from.sensor_types().await? {
        to.put_sensor_type(t).await?;
        copied.sensor_types += 1;
    }
    for t in from.tokens().await? {
        to.insert_token(t).await?;
        copied.tokens += 1;
    }
    let mut after = None;
    loop {
        let page = from.export_calibrations(after, PAGE).await?;
        let Some(last) = page.last() else { break };
        after = Some(last.id);
        for c in page {
            to.insert_calibration(c, None).await?;
            copied.calibrations += 1;
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
            if let Some(t) = s.sensor_type {
                to.assign_sensor_type(s.sensor_id, t).await?;
                copied.typed_sensors += 1;
            }
        }
    }
    for k in from
        .done_keys(now.plus_seconds(-IDEMPOTENCY_RETENTION_SECONDS))
        .await?
    {
        to.put_done_key(k).await?;
        copied.idempotency_keys += 1;
    }
    Ok(copied)
}
