//! The driver's and the pool's errors mapped to [`StoreError`], keeping them
//! as the source.
//!
//! By SQLSTATE class: integrity violations (23) — and the schema's own
//! refusals, raised as such — are constraints; data exceptions (22) and
//! syntax or access errors (42) are accelcal's bugs, reported like
//! constraints (500, never retried); everything else — no connection
//! (08), the server shutting down or starting (57), out of resources (53,
//! 58), a serialization failure or deadlock (40) — is the database being
//! unavailable (503, retried). An error without SQLSTATE is the connection's.

use deadpool_postgres::PoolError;
use tokio_postgres::error::SqlState;

use crate::store::StoreError;

/// Maps a driver error.
pub fn map(e: tokio_postgres::Error) -> StoreError {
    let Some(code) = e.code() else {
        return StoreError::Unavailable(Box::new(e));
    };
    match code.code().get(..2) {
        Some("23" | "22" | "42") => StoreError::Constraint(Box::new(e)),
        _ if *code == SqlState::RAISE_EXCEPTION => StoreError::Constraint(Box::new(e)),
        _ => StoreError::Unavailable(Box::new(e)),
    }
}

/// Maps a pool error: no connection could be had in time.
pub fn pool(e: PoolError) -> StoreError {
    match e {
        PoolError::Backend(e) => map(e),
        other => StoreError::Unavailable(Box::new(other)),
    }
}

/// A column that did not decode.
pub fn decode(column: &str, e: impl Into<crate::store::BoxError>) -> StoreError {
    StoreError::corrupt(format!("column `{column}`"), e)
}
