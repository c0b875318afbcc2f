//! What control systems use: the latest coefficients, and compensation of
//! raw outputs with them.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::problem::Problem;
use super::rendered::{APPLICATION_JSON, ById};
use super::sensors::{latest_id, sensor};
use crate::domain::auth::{Principal, Role};
use crate::domain::compensate::{CompensateRequest, Compensated};
use crate::domain::text::echo;
use crate::domain::timestamp::Timestamp;
use crate::store::CalibrationSummary;

/// What a control system loads: the fused coefficients of one calibration.
#[derive(Debug, Serialize, ToSchema)]
pub struct Coefficients {
    /// The sensor.
    sensor_id: String,
    /// The calibration they come from (the latest `performed_at`).
    calibration_id: Uuid,
    /// When that calibration was performed.
    performed_at: Timestamp,
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
}

impl From<CalibrationSummary> for Coefficients {
    fn from(summary: CalibrationSummary) -> Self {
        Coefficients {
            sensor_id: summary.sensor_id,
            calibration_id: summary.id,
            performed_at: summary.performed_at,
            unit: summary.unit,
            model: summary.model,
            coefficients: summary.coefficients,
            std_errors: summary.std_errors,
        }
    }
}

/// `GET /v1/sensors/{sensor_id}/coefficients`: the latest calibration's fused values.
#[utoipa::path(
    get,
    path = "/v1/sensors/{sensor_id}/coefficients",
    tag = "sensors",
    operation_id = "getCoefficients",
    summary = "The latest calibration's fused coefficients, for control systems.",
    params(super::openapi::SensorIdPath),
    responses(
        (status = 200, description = "The coefficients.", body = Coefficients),
        (status = 401, response = super::openapi::Unauthorized),
        (status = 404, response = super::openapi::NotFound),
        (status = 503, response = super::openapi::Unavailable),
        (status = "default", response = super::openapi::ProblemResponse),
    )
)]
pub async fn coefficients(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    // Which calibration is the latest, then its rendering if kept; the
    // summary itself is read only to render a calibration not kept yet.
    let id = latest_id(&state, &sensor_id).await?;
    let body = match state.rendered.get(&id) {
        Some(body) => body,
        None => state
            .rendered
            .get_or_render(sensor(&state, &sensor_id).await?.latest)?,
    };
    Ok(([(header::CONTENT_TYPE, APPLICATION_JSON.clone())], body).into_response())
}

/// The answers of `GET /v1/sensors/{sensor_id}/coefficients`, rendered once
/// per calibration ([`super::rendered`]).
#[derive(Debug)]
pub struct Rendered(ById);

/// Calibrations whose coefficients are kept rendered (each a few hundred
/// bytes).
pub const RENDERED: usize = 4096;

impl Default for Rendered {
    fn default() -> Self {
        Rendered(ById::new(RENDERED))
    }
}

impl Rendered {
    /// The kept rendering of calibration `id`, if any.
    pub fn get(&self, id: &Uuid) -> Option<Bytes> {
        self.0.get(id)
    }

    /// The rendered [`Coefficients`] of `latest`, from memory when they
    /// were rendered before.
    pub fn get_or_render(&self, latest: CalibrationSummary) -> Result<Bytes, Problem> {
        let id = latest.id;
        if let Some(body) = self.0.get(&id) {
            return Ok(body);
        }
        let body = Bytes::from(
            serde_json::to_vec(&Coefficients::from(latest)).map_err(|e| {
                tracing::error!(error = %e, "rendering coefficients failed");
                Problem::internal()
            })?,
        );
        self.0.insert(id, body.clone());
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
    description = "Inverts the model of the sensor's latest calibration (or the one \\
        named by `calibration_id`): closed form when the model is linear in \\
        `a_i`, Newton's iteration otherwise. `a_p` and `a_o`, when given, \\
        hold one known value per output (default 0).",
    params(super::openapi::SensorIdPath),
    request_body(content((CompensateRequest = "application/json"))),
    responses(
        (status = 200, description = "One input acceleration per output.", body = Compensated),
        (status = 400, response = super::openapi::BadRequest),
        (status = 401, response = super::openapi::Unauthorized),
        (status = 404, response = super::openapi::NotFound),
        (status = 413, response = super::openapi::TooLarge),
        (status = 415, response = super::openapi::UnsupportedMediaType),
        (status = 422, response = super::openapi::Invalid),
        (status = 503, response = super::openapi::Unavailable),
        (status = "default", response = super::openapi::ProblemResponse),
    )
)]
pub async fn compensate(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    body: Body,
) -> Result<Json<Compensated>, Problem> {
    require(&principal, Role::Reader)?;
    let request = body.json::<CompensateRequest>()?.check()?;
    let summary = match request.calibration_id {
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
    let a_i = request.compensate(&summary.coefficients, summary.id)?;
    Ok(Json(Compensated {
        sensor_id: summary.sensor_id,
        calibration_id: summary.id,
        unit: summary.unit,
        a_i,
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
        let body = r.get_or_render(latest(1, -8.4e-4)).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        assert_eq!(
            v,
            serde_json::json!({
                "sensor_id": "S",
                "calibration_id": Uuid::from_u128(1),
                "performed_at": "2026-01-01T00:00:00.000000Z",
                "unit": "mA",
                "model": ["k0", "ki"],
                "coefficients": {"k0": -8.4e-4, "ki": -1.216},
                "std_errors": {"k0": 1e-6, "ki": 2e-6},
            })
        );
        // A second read of that calibration is the kept bytes.
        let again = r.get_or_render(latest(1, 0.5)).unwrap();
        assert_eq!(again, body);
        assert_eq!(r.len(), 1);
        // Another calibration is rendered on its own.
        let other = r.get_or_render(latest(2, 0.5)).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&other).unwrap();
        assert_eq!(v["coefficients"]["k0"], 0.5);
        assert_eq!(r.len(), 2);
    }

    #[test]
    fn at_most_so_many_calibrations_are_kept() {
        let r = Rendered::default();
        for id in 0..(RENDERED as u128 + 10) {
            r.get_or_render(latest(id, 0.0)).unwrap();
        }
        assert_eq!(r.len(), RENDERED);
        // The newest is among them.
        let newest = Uuid::from_u128(RENDERED as u128 + 9);
        assert!(r.0.contains(&newest));
    }
}
