//! A temperature model's constituents checked where it is stored: the
//! calibrations a model was fitted from ([`NewCalibration::fitted_from`])
//! are read by its request, and a reviewer may reject, withdraw or
//! supersede one — or a nonconformity hold it — before the model is
//! written. So the transaction that stores the model reads their states
//! again, after it has locked their rows (on PostgreSQL `FOR SHARE`, which
//! an act's `FOR NO KEY UPDATE` of a calibration waits for and makes
//! wait; on SQLite the one writer orders every write), and refuses the
//! model with [`StoreError::Conflict`] if one no longer makes a model
//! ([`unusable`]). An act that commits first is seen by the model's
//! check; a model that commits first is seen by the act's
//! ([`fitted_into_sql`](super::fitted_into_sql)): never neither.

use uuid::Uuid;

use super::{NewCalibration, StoreError};
use crate::domain::review::State;
use crate::domain::thermal::combine::unusable;

/// The state of calibration `p` (a placeholder of its id), as `state`.
pub fn state_sql(p: &str) -> String {
    format!(
        "SELECT {} AS state FROM calibrations c WHERE c.id = {p}",
        crate::state_sql!()
    )
}

/// Refuses `n` if the calibration `id` it was fitted from, in `state`
/// now (`None`: not stored), cannot make a model.
pub fn judge(n: &NewCalibration, id: Uuid, state: Option<State>) -> Result<(), StoreError> {
    let why = match state {
        None => Some(format!("calibration {id} is not stored")),
        Some(state) => unusable(id, state),
    };
    match why {
        None => Ok(()),
        Some(why) => Err(StoreError::Conflict(format!(
            "temperature model {} was not stored: {why} (its state changed while the model was \
             fitted; fit the model again)",
            n.id
        ))),
    }
}
