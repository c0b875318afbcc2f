//! What control systems use: the latest coefficients, and compensation of
//! raw outputs with them.

use accelcal_core::decision::Verdict;
use axum::Json;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use uuid::Uuid;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::lookup::{latest_id, sensor};
use super::problem::{Kind, Problem};
use super::query::Params;
use super::rendered::{APPLICATION_JSON, ById};
use crate::app::thermal::triad::elements_at;
use crate::domain::auth::{Principal, Role};
use crate::domain::compensate::{
    CompensateRequest, Compensated, TemperatureUsed, Temperatures, no_model, outside_range,
};
use crate::domain::field::Invalid;
use crate::domain::review::{Basis, State as ReviewState};
use crate::domain::text::echo;
use crate::domain::timestamp::Timestamp;
use crate::domain::usability::Usability;
use crate::store::CalibrationSummary;

mod temperature;

/// What a control system loads: the fused coefficients of one calibration,
/// and whether to use them.
#[derive(Debug, Serialize, ToSchema)]
pub struct Coefficients {
    /// The sensor.
    sensor_id: String,
    /// The calibration they come from (the latest `performed_at`).
    calibration_id: Uuid,
    /// When that calibration was performed.
    performed_at: Timestamp,
    /// Its verdict against the sensor type's limits (null when untyped).
    #[schema(value_type = Option<crate::domain::schema::VerdictSchema>)]
    verdict: Option<Verdict>,
    /// When the sensor is due again (null when untyped).
    due_at: Option<Timestamp>,
    /// The sensor's status, whether to use the coefficients, and why not.
    #[serde(flatten)]
    usability: Usability,
    /// Unit of the outputs and of every coefficient.
    unit: String,
    /// Model terms.
    #[schema(value_type = crate::domain::schema::ModelSchema)]
    model: accelcal_core::Model,
    /// Fused coefficients.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    coefficients: accelcal_core::TermMap<f64>,
    /// Their standard errors.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    std_errors: accelcal_core::TermMap<f64>,
    /// A triad's b, S and T with their standard errors (absent for a
    /// single-axis sensor; a triad's `coefficients` are empty).
    #[serde(skip_serializing_if = "Option::is_none")]
    triad: Option<crate::store::TriadElements>,
    /// For a temperature model: the temperature `coefficients` and
    /// `std_errors` are evaluated at (`temperature_c`, else `T_ref`), the
    /// model's range, and whether it was extrapolated.
    #[serde(skip_serializing_if = "Option::is_none")]
    temperature: Option<TemperatureUsed>,
    /// Which calibrations are served: `not_rejected` (every calibration not
    /// rejected or withdrawn) or `approved_only` (`--require-approval`).
    basis: Basis,
}

impl Coefficients {
    /// The coefficients of `summary`, judged at `now`, served on `basis`
    /// (which it counts on: it is the sensor's latest on it).
    fn of(summary: CalibrationSummary, now: Timestamp, basis: Basis) -> Self {
        let temperature = match (summary.thermal.as_deref(), summary.thermal_triad.as_deref()) {
            (Some(m), _) => Some(TemperatureUsed::of(m, Temperatures::One(m.reference_c()))),
            (None, Some(m)) => Some(TemperatureUsed::of(m, Temperatures::One(m.reference_c()))),
            (None, None) => None,
        };
        Coefficients {
            temperature,
            sensor_id: summary.sensor_id,
            calibration_id: summary.id,
            performed_at: summary.performed_at,
            verdict: summary.verdict,
            due_at: summary.due_at,
            usability: Usability::of(summary.verdict, summary.due_at, now)
                .in_state(summary.state, basis),
            unit: summary.unit,
            model: summary.model,
            coefficients: summary.coefficients,
            triad: summary.triad.map(|t| *t),
            std_errors: summary.std_errors,
            basis,
        }
    }
}

/// The query of `/coefficients` and `/compensate`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct RequireQuery {
    /// `usable`: answer 409 (`not-usable`) instead of coefficients whose
    /// calibration failed or is overdue.
    #[param(value_type = Option<String>, pattern = "^usable$")]
    require: Option<String>,
}

impl RequireQuery {
    /// Whether `require=usable` was asked.
    fn usable(&self) -> Result<bool, Problem> {
        match self.require.as_deref() {
            None => Ok(false),
            Some("usable") => Ok(true),
            Some(_) => Err(Problem::bad_parameter(
                "require",
                "must be `usable` (the only requirement there is)",
            )),
        }
    }
}

/// The query of `/coefficients`: [`RequireQuery`]'s, and a temperature.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct CoefficientsQuery {
    /// `usable`: answer 409 (`not-usable`) instead of coefficients whose
    /// calibration failed or is overdue.
    #[param(value_type = Option<String>, pattern = "^usable$")]
    require: Option<String>,
    /// The sensor's temperature, °C: the coefficients of a temperature
    /// model evaluated there, with their standard uncertainties (422 for a
    /// calibration that is not one, or outside its range unless
    /// `allow_extrapolation`).
    #[param(minimum = -100.0, maximum = 200.0)]
    temperature_c: Option<f64>,
    /// `true`: evaluate a temperature model outside its range too (the
    /// answer says `extrapolated` and by how many kelvin); default false.
    allow_extrapolation: Option<bool>,
}

/// The 409 for coefficients of `summary` whose usability is `u`.
fn refuse_unusable(summary: &CalibrationSummary, u: &Usability) -> Result<(), Problem> {
    if u.usable {
        return Ok(());
    }
    let why: Vec<&str> = u.reasons.iter().map(|r| r.detail.as_str()).collect();
    Err(Problem::new(
        Kind::NotUsable,
        format!(
            "the coefficients of sensor `{}` (calibration {}) are not usable: {}",
            echo(&summary.sensor_id),
            summary.id,
            why.join("; ")
        ),
    ))
}

/// A sensor's latest approved calibration, or 404 (`--require-approval`).
async fn latest_approved(state: &AppState, sensor_id: &str) -> Result<CalibrationSummary, Problem> {
    // The sensor first: an unknown one is told apart from one with
    // nothing approved.
    sensor(state, sensor_id).await?;
    state
        .store
        .latest_approved(sensor_id.to_owned())
        .await?
        .ok_or_else(|| {
            Problem::not_found(format!(
                "sensor `{}` has no approved calibration (only approved calibrations are \
                 served: --require-approval)",
                echo(sensor_id)
            ))
        })
}

/// `GET /v1/sensors/{sensor_id}/coefficients`: the latest calibration's fused values.
#[utoipa::path(
    get,
    path = "/v1/sensors/{sensor_id}/coefficients",
    tag = "sensors",
    operation_id = "getCoefficients",
    summary = "The latest calibration's fused coefficients, for control systems.",
    description = "With the calibration's verdict, due date, the sensor's status, \
        `usable` and the `reasons` why not: coefficients whose calibration failed \
        or is overdue are not usable. With `require=usable` such coefficients are \
        a 409 instead. The latest calibration is the latest not rejected or \
        withdrawn, or with `--require-approval` the latest approved (`basis` \
        says which); a sensor with none is a 404. A temperature model's coefficients are \
        those at its `T_ref` unless `temperature_c` asks for another temperature (`temperature` \
        says which, and the model's range).",
    params(super::openapi::SensorIdPath, CoefficientsQuery),
    responses(
        (status = 200, description = "The coefficients.", body = Coefficients),
        (status = 400, response = super::openapi::BadRequest),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::NotUsable),
        (status = 422, response = super::openapi::ProblemResponse),
        super::openapi::Always,
    )
)]
pub async fn coefficients(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    Params(query): Params<CoefficientsQuery>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let usable = RequireQuery {
        require: query.require,
    }
    .usable()?;
    if let Some(t) = query.temperature_c {
        let allow = query.allow_extrapolation.unwrap_or(false);
        return temperature::at_temperature(&state, &sensor_id, t, allow, usable).await;
    }
    let now = Timestamp::now();
    if state.web.basis == Basis::ApprovedOnly {
        let latest = latest_approved(&state, &sensor_id).await?;
        if usable {
            let usability = Usability::of(latest.verdict, latest.due_at, now)
                .in_state(latest.state, state.web.basis);
            refuse_unusable(&latest, &usability)?;
        }
        let body = state.rendered.get_or_render(latest, now, state.web.basis)?;
        return Ok(([(header::CONTENT_TYPE, APPLICATION_JSON.clone())], body).into_response());
    }
    // Which calibration is the latest, then its rendering if kept and still
    // right; the summary itself is read only to render, or to refuse.
    let (id, latest_state) = latest_id(&state, &sensor_id).await?;
    let kept = if usable {
        None
    } else {
        state.rendered.get(id, latest_state, now)
    };
    let body = match kept {
        Some(body) => body,
        None => {
            let latest = sensor(&state, &sensor_id).await?.latest;
            if usable {
                let usability = Usability::of(latest.verdict, latest.due_at, now)
                    .in_state(latest.state, state.web.basis);
                refuse_unusable(&latest, &usability)?;
            }
            state.rendered.get_or_render(latest, now, state.web.basis)?
        }
    };
    Ok(([(header::CONTENT_TYPE, APPLICATION_JSON.clone())], body).into_response())
}

/// The answers of `GET /v1/sensors/{sensor_id}/coefficients`, rendered once
/// per calibration ([`super::rendered`]).
#[derive(Debug)]
pub struct Rendered(ById<(Uuid, ReviewState)>);

/// Calibrations whose coefficients are kept rendered (each a few hundred
/// bytes).
pub const RENDERED: usize = 4096;

impl Default for Rendered {
    fn default() -> Self {
        Rendered(ById::new(RENDERED))
    }
}

impl Rendered {
    /// The kept rendering of calibration `id` in `state`, if any and still
    /// right at `now` (its status changes 30 days before the due date and
    /// at it; its usability with its state).
    pub fn get(&self, id: Uuid, state: ReviewState, now: Timestamp) -> Option<Bytes> {
        self.0.get_at(&(id, state), now)
    }

    /// The rendered [`Coefficients`] of `latest` at `now` on `basis` (the
    /// process's: one rendering per calibration), from memory when they
    /// were rendered before and are still right.
    pub fn get_or_render(
        &self,
        latest: CalibrationSummary,
        now: Timestamp,
        basis: Basis,
    ) -> Result<Bytes, Problem> {
        let key = (latest.id, latest.state);
        if let Some(body) = self.0.get_at(&key, now) {
            return Ok(body);
        }
        let until = Usability::valid_until(latest.due_at, now);
        let body = Bytes::from(
            serde_json::to_vec(&Coefficients::of(latest, now, basis)).map_err(|e| {
                tracing::error!(error = %e, "rendering coefficients failed");
                Problem::internal()
            })?,
        );
        self.0.insert_until(key, body.clone(), until);
        Ok(body)
    }

    /// Calibrations held rendered now.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether none is.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// `POST /v1/sensors/{sensor_id}/compensate`: input accelerations (g) from
/// raw outputs, with the latest calibration or the one named.
#[utoipa::path(
    post,
    path = "/v1/sensors/{sensor_id}/compensate",
    tag = "sensors",
    operation_id = "compensate",
    summary = "Input accelerations (g) from raw outputs.",
    description = "Inverts the model of the sensor's latest calibration (or the one \
        named by `calibration_id`): closed form when the model is linear in \
        `a_i`, Newton's iteration otherwise. `a_p` and `a_o`, when given, \
        hold one known value per output; when omitted they are taken as 0, and \
        `assumed_zero` names those the model has terms in. The answer says \
        whether the calibration's coefficients are usable; with \
        `require=usable`, unusable ones are a 409.",
    params(super::openapi::SensorIdPath, RequireQuery),
    request_body(content((CompensateRequest = "application/json"))),
    responses(
        (status = 200, description = "One input acceleration per output.", body = Compensated),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::NotUsable),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn compensate(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    Params(query): Params<RequireQuery>,
    body: Body,
) -> Result<Json<Compensated>, Problem> {
    require(&principal, Role::Reader)?;
    let usable = query.usable()?;
    let request = body.json::<CompensateRequest>()?.check()?;
    let basis = state.web.basis;
    let summary = match request.calibration_id {
        None if basis == Basis::ApprovedOnly => latest_approved(&state, &sensor_id).await?,
        None => sensor(&state, &sensor_id).await?.latest,
        Some(id) => state
            .store
            .calibration_summary(id)
            .await?
            .filter(|s| s.sensor_id == sensor_id)
            .ok_or_else(|| {
                Problem::not_found(format!(
                    "sensor `{}` has no calibration `{id}`",
                    echo(&sensor_id)
                ))
            })?,
    };
    let usability = Usability::of(summary.verdict, summary.due_at, Timestamp::now())
        .in_state(summary.state, basis);
    if usable {
        refuse_unusable(&summary, &usability)?;
    }
    if request.temperature_c.is_some()
        && summary.thermal.is_none()
        && summary.thermal_triad.is_none()
    {
        return Err(Problem::validation(Invalid::one(
            "/temperature_c",
            no_model(summary.id),
        )));
    }
    let (a_i, g, temperature) = match (&summary.triad, &summary.thermal, &summary.thermal_triad) {
        (Some(_), _, Some(model)) => {
            let (g, used) = request.compensate_triad_at(model, summary.id)?;
            (None, Some(g), Some(used))
        }
        (Some(t), _, None) => (
            None,
            Some(request.compensate_triad(&t.model(), summary.id)?),
            None,
        ),
        (None, Some(model), _) => {
            let (a_i, used) = request.compensate_at(model, summary.id)?;
            (Some(a_i), None, Some(used))
        }
        (None, None, _) => (
            Some(request.compensate(&summary.coefficients, summary.id)?),
            None,
            None,
        ),
    };
    Ok(Json(Compensated {
        assumed_zero: request.assumed_zero(&summary.model),
        usability,
        sensor_id: summary.sensor_id,
        calibration_id: summary.id,
        performed_at: summary.performed_at,
        verdict: summary.verdict,
        due_at: summary.due_at,
        unit: summary.unit,
        a_i,
        g,
        temperature,
        state: summary.state,
        basis,
    }))
}

#[cfg(test)]
mod tests {
    use accelcal_core::{Term, TermMap};

    use super::*;

    fn latest(id: u128, k0: f64) -> CalibrationSummary {
        let mut summary = CalibrationSummary::for_test(id, "S", k0, -1.216);
        summary.std_errors = TermMap(vec![(Term::K0, 1e-6), (Term::Ki, 2e-6)]);
        summary
    }

    /// The kept rendering is the document itself, field for field.
    #[test]
    fn the_rendering_is_the_coefficients_document() {
        let r = Rendered::default();
        let now = Timestamp::parse("2026-06-01T00:00:00Z").unwrap();
        let body = r
            .get_or_render(latest(1, -8.4e-4), now, Basis::NotRejected)
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(
            v,
            serde_json::json!({
                "sensor_id": "S",
                "calibration_id": Uuid::from_u128(1),
                "performed_at": "2026-01-01T00:00:00.000000Z",
                "verdict": null,
                "due_at": null,
                "status": "unknown",
                "usable": true,
                "reasons": [],
                "unit": "mA",
                "model": ["k0", "ki"],
                "coefficients": {"k0": -8.4e-4, "ki": -1.216},
                "std_errors": {"k0": 1e-6, "ki": 2e-6},
                "basis": "not_rejected",
            })
        );
        // A second read of that calibration is the kept bytes.
        let again = r
            .get_or_render(latest(1, 0.5), now, Basis::NotRejected)
            .unwrap();
        assert_eq!(again, body);
        assert_eq!(r.len(), 1);
        // Another calibration is rendered on its own.
        let other = r
            .get_or_render(latest(2, 0.5), now, Basis::NotRejected)
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&other).unwrap();
        assert_eq!(v["coefficients"]["k0"], 0.5);
        assert_eq!(r.len(), 2);
    }

    /// A rendering holds its status until the status can change: kept up
    /// to 30 days before the due date, rendered again after it (due soon),
    /// and again after the due date (overdue, not usable).
    #[test]
    fn a_rendering_is_renewed_when_its_status_can_change() {
        let r = Rendered::default();
        let at = |s: &str| Timestamp::parse(s).unwrap();
        let mut s = latest(7, 1e-3);
        s.verdict = Some(Verdict::Pass);
        s.due_at = Some(at("2026-07-01T00:00:00Z"));
        let read = |now: &str| {
            let body = r
                .get_or_render(s.clone(), at(now), Basis::NotRejected)
                .unwrap();
            let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
            (
                v["status"].as_str().unwrap().to_owned(),
                v["usable"].as_bool().unwrap(),
            )
        };
        assert_eq!(read("2026-05-01T00:00:00Z"), ("ok".into(), true));
        assert!(
            r.get(
                Uuid::from_u128(7),
                ReviewState::Submitted,
                at("2026-06-01T00:00:00Z")
            )
            .is_some()
        );
        assert!(
            r.get(
                Uuid::from_u128(7),
                ReviewState::Submitted,
                at("2026-06-01T00:00:01Z")
            )
            .is_none()
        );
        assert_eq!(read("2026-06-15T00:00:00Z"), ("due_soon".into(), true));
        assert_eq!(read("2026-07-02T00:00:00Z"), ("overdue".into(), false));
        // Overdue stays overdue: kept for ever.
        assert!(
            r.get(
                Uuid::from_u128(7),
                ReviewState::Submitted,
                at("2030-01-01T00:00:00Z")
            )
            .is_some()
        );
    }

    #[test]
    fn at_most_so_many_calibrations_are_kept() {
        let r = Rendered::default();
        for id in 0..(RENDERED as u128 + 10) {
            r.get_or_render(latest(id, 0.0), Timestamp::now(), Basis::NotRejected)
                .unwrap();
        }
        assert_eq!(r.len(), RENDERED);
        // The newest is among them.
        let newest = Uuid::from_u128(RENDERED as u128 + 9);
        assert!(r.0.contains(&(newest, ReviewState::Submitted)));
    }

    /// A calibration put under review renders anew (its key is its id and
    /// state): not usable, with the reason, while the rendering of its
    /// earlier state is not served for it.
    #[test]
    fn a_held_calibration_is_rendered_unusable() {
        let r = Rendered::default();
        let now = Timestamp::parse("2026-05-01T00:00:00Z").unwrap();
        let s = latest(7, 1e-3);
        r.get_or_render(s.clone(), now, Basis::NotRejected).unwrap();
        assert!(r.get(s.id, ReviewState::UnderReview, now).is_none());
        let held = CalibrationSummary {
            state: ReviewState::UnderReview,
            ..s
        };
        let body = r.get_or_render(held, now, Basis::NotRejected).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(v["usable"], false);
        assert_eq!(v["reasons"][0]["reason"], "under_review");
    }
}
