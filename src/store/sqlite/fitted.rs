//! A temperature model's constituents checked in the transaction that
//! stores it ([`crate::store::fitted`]): the one writer orders the model's
//! write and every act on a calibration, so each state read here is the
//! state the model commits against.

use rusqlite::Connection;

use super::rows;
use crate::store::fitted::{judge, state_sql};
use crate::store::{NewCalibration, StoreError};

/// Refuses `n` ([`crate::store::StoreError::Conflict`]) if a calibration
/// it was fitted from no longer makes a model; nothing to do for a record
/// fitted from none.
pub fn check(tx: &Connection, n: &NewCalibration) -> Result<(), StoreError> {
    let sql = state_sql("?1");
    for &id in &n.fitted_from {
        let state = rows::first(tx, &sql, [id.to_string()], rows::state)?;
        judge(n, id, state)?;
    }
    Ok(())
}
