//! A temperature model's constituents checked in the transaction that
//! stores it ([`crate::store::fitted`]): their rows locked `FOR SHARE`, in
//! id order, then each one's state read by a statement of its own — under
//! READ COMMITTED a new statement sees what an act that held the row
//! committed while this one waited for it.

use deadpool_postgres::Transaction;

use super::errors::map;
use super::rows;
use crate::store::fitted::{judge, state_sql};
use crate::store::{NewCalibration, StoreError};

/// Refuses `n` ([`crate::store::StoreError::Conflict`]) if a calibration
/// it was fitted from no longer makes a model; nothing to do for a record
/// fitted from none.
pub async fn check(tx: &Transaction<'_>, n: &NewCalibration) -> Result<(), StoreError> {
    if n.fitted_from.is_empty() {
        return Ok(());
    }
    tx.execute(
        "SELECT 1 FROM calibrations WHERE id = ANY($1) ORDER BY id FOR SHARE",
        &[&n.fitted_from],
    )
    .await
    .map_err(map)?;
    let sql = state_sql("$1");
    for &id in &n.fitted_from {
        let state = match tx.query_opt(&sql, &[&id]).await.map_err(map)? {
            Some(row) => Some(rows::state(&row)?),
            None => None,
        };
        judge(n, id, state)?;
    }
    Ok(())
}
