//! What control systems use: the latest coefficients, and compensation of
//! raw outputs with them.

use axum::Json;
use axum::extract::{Path, State};
use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::problem::Problem;
use super::sensors::sensor;
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
) -> Result<Json<Coefficients>, Problem> {
    require(&principal, Role::Reader)?;
    Ok(Json(sensor(&state, &sensor_id).await?.latest.into()))
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
