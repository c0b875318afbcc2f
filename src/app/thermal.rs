//! Identifying a single axis's coefficients over temperature (issue 45):
//! a submission whose runs were made at several temperatures, read,
//! checked and identified set point by set point on the compute pool, and
//! each coefficient's polynomial answered ([`crate::domain::thermal`]).
//! A triad's `b` and `S` likewise, from runs with known orientations.
//! Nothing is stored: the thermal calibration kind — its record, review,
//! certificate and compensation at a temperature — builds on this.

use super::subject::station;
use super::{Error, Lab, Upload};
use crate::domain::auth::Principal;
use crate::domain::field::Loc;
use crate::domain::submission::evaluate;
use crate::domain::thermal::{ThermalModel, TriadThermalModel, model, triad_model};
use crate::domain::timestamp::Timestamp;

/// The temperature model of `upload` for `principal`, its runs grouped
/// within `tolerance_k` and each polynomial fitted with `options`
/// (`crate::domain::thermal::ThermalParams::checked`). A sensor type
/// or reference standards are refused rather than ignored: nothing here
/// judges against limits or budgets with a standard yet.
pub async fn identify(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    tolerance_k: f64,
    options: accelcal_core::thermal::Options,
) -> Result<ThermalModel, Error> {
    let who = principal.clone();
    lab.compute_for(
        upload.bytes.len(),
        move || -> Result<ThermalModel, Error> {
            let e = evaluate(upload.media, &upload.bytes, Timestamp::now())?;
            station(&who, e.submission.station_id.as_deref())?;
            if e.submission.sensor_type.is_some() {
                return Err(not_yet("sensor_type", "a sensor type's decision"));
            }
            if e.submission.standards.is_some() {
                return Err(not_yet("standards", "the reference standards' budget"));
            }
            Ok(model(&e.submission, tolerance_k, &options)?)
        },
    )
    .await?
}

/// The temperature model of the triad `upload`, its runs grouped within
/// `tolerance_k` and each element's polynomial fitted with `options`; as
/// for a single axis, a sensor type or reference standards are refused
/// rather than ignored.
pub async fn identify_triad(
    lab: &Lab,
    upload: Upload,
    tolerance_k: f64,
    options: accelcal_core::thermal::Options,
) -> Result<TriadThermalModel, Error> {
    lab.compute_for(
        upload.bytes.len(),
        move || -> Result<TriadThermalModel, Error> {
            let sub = super::triad::read(&upload)?;
            if sub.sensor_type.is_some() {
                return Err(not_yet("sensor_type", "a sensor type's decision"));
            }
            if !sub.standards.is_empty() {
                return Err(not_yet("standards", "the reference standards' budget"));
            }
            Ok(triad_model(&sub, tolerance_k, &options)?)
        },
    )
    .await?
}

/// The refusal of `key`, which names `what` a temperature model does not
/// apply yet.
fn not_yet(key: &str, what: &str) -> Error {
    Error::invalid(
        Loc::Root.key(key),
        format!("{what} is not applied to a temperature model yet (issue 45 item 4): omit it"),
    )
}
