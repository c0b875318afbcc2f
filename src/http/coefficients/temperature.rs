//! The coefficients of a temperature model at a temperature (issue 45
//! item 3): a single axis's coefficients, or a triad's `b`, `S` and
//! `T = S⁻¹`, evaluated from the sensor's latest calibration's model —
//! refused outside its range unless extrapolation is allowed, and for a
//! calibration that is no model.

use axum::Json;
use axum::response::{IntoResponse, Response};

use super::*;

/// The coefficients of `sensor_id`'s latest calibration, a temperature
/// model, evaluated at `t` °C (extrapolated only when `allow`).
pub(super) async fn at_temperature(
    state: &AppState,
    sensor_id: &str,
    t: f64,
    allow: bool,
    usable: bool,
) -> Result<Response, Problem> {
    let limits = crate::domain::limits::TEMPERATURE_C;
    if !limits.contains(&t) {
        return Err(Problem::bad_parameter(
            "temperature_c",
            format!(
                "must be a temperature from {} to {} °C",
                limits.start(),
                limits.end()
            ),
        ));
    }
    let now = Timestamp::now();
    let basis = state.web.basis;
    let latest = if basis == Basis::ApprovedOnly {
        latest_approved(state, sensor_id).await?
    } else {
        sensor(state, sensor_id).await?.latest
    };
    if usable {
        let usability =
            Usability::of(latest.verdict, latest.due_at, now).in_state(latest.state, basis);
        refuse_unusable(&latest, &usability)?;
    }
    let refused = |detail: String| {
        Problem::new(Kind::Validation, format!("temperature_c {detail}")).naming("temperature_c")
    };
    if let Some(model) = latest.thermal_triad.as_deref().cloned() {
        let outside = model.at(t).outside_k;
        if outside > 0.0 && !allow {
            return Err(refused(outside_range(t, outside, &model, latest.id)));
        }
        let elements = elements_at(&model, t).ok_or_else(|| {
            refused(format!(
                "is {t} °C, where calibration {}'s S is singular: no coefficients there",
                latest.id
            ))
        })?;
        let mut c = Coefficients::of(latest, now, basis);
        c.triad = Some(elements);
        c.temperature = Some(TemperatureUsed::of(&model, Temperatures::One(t)));
        return Ok(Json(c).into_response());
    }
    let Some(model) = latest.thermal.as_deref().cloned() else {
        return Err(refused(no_model(latest.id)));
    };
    let at = model.at(t);
    if at.outside_k > 0.0 && !allow {
        return Err(refused(outside_range(t, at.outside_k, &model, latest.id)));
    }
    let mut c = Coefficients::of(latest, now, basis);
    c.coefficients = at.coefficients;
    c.std_errors = at.std_errors;
    c.temperature = Some(TemperatureUsed::of(&model, Temperatures::One(t)));
    Ok(Json(c).into_response())
}
