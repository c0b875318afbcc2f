//! Sensor types: `PUT` (admin), and reading them.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::Response;
use serde::Serialize;
use utoipa::ToSchema;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::conditional::{precondition, tagged, written};
use super::problem::Problem;
use crate::app::definitions;
use crate::domain::auth::{Principal, Role};
use crate::domain::limits::MAX_ID_CHARS;
use crate::domain::sensor_types::{SensorType, SensorTypeBody};
use crate::domain::text::{Chars, check_str, echo};
use crate::domain::timestamp::Timestamp;
use crate::store::conditional::etag;

fn unknown_type(type_id: &str) -> Problem {
    Problem::not_found(format!("no sensor type `{}`", echo(type_id)))
}

/// `PUT /v1/sensor-types/{type_id}` (admin): creates (201) or replaces
/// (200) a type. Stored calibrations keep the decision made with the type
/// in force when they were submitted.
#[utoipa::path(
    put,
    path = "/v1/sensor-types/{type_id}",
    tag = "sensor-types",
    operation_id = "putSensorType",
    summary = "Create or replace a sensor type (admin).",
    params(("type_id" = crate::domain::schema::Identifier, Path, description = "The type's id."),
        super::openapi::ConditionalHeaders),
    request_body(content((SensorTypeBody = "application/json",
        example = json!({"label": "Navigation grade", "unit": "mA", "limits": {"k0": {"min": -0.001, "max": 0.001}, "kp": {"min": -0.01, "max": 0.01}}, "decision_rule": "guarded", "coverage_probability": 0.9545, "interval_days": 365})))),
    responses(
        (status = 200, description = "Replaced.", body = SensorType, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 201, description = "Created.", body = SensorType, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 403, response = super::openapi::Forbidden),
        (status = 412, response = super::openapi::PreconditionFailed),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn put(
    State(state): State<AppState>,
    principal: Principal,
    Path(type_id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Admin)?;
    if let Err(why) = check_str(&type_id, MAX_ID_CHARS, Chars::Identifier) {
        return Err(Problem::bad_request(format!("the type id {why}")));
    }
    let pre = precondition(&headers)?;
    let t = body
        .json::<SensorTypeBody>()?
        .check(type_id, Timestamp::now())?;
    written(
        definitions::sensor_type(&state.lab, &principal, t, pre).await?,
        "sensor type",
    )
}

/// A list of sensor types.
#[derive(Debug, Serialize, ToSchema)]
pub struct SensorTypeList {
    /// Every type, in id order.
    items: Vec<SensorType>,
}

/// `GET /v1/sensor-types`.
#[utoipa::path(
    get,
    path = "/v1/sensor-types",
    tag = "sensor-types",
    operation_id = "listSensorTypes",
    summary = "Every sensor type.",
    responses(
        (status = 200, description = "The types.", body = SensorTypeList),
        super::openapi::Always,
    )
)]
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
) -> Result<Json<SensorTypeList>, Problem> {
    require(&principal, Role::Reader)?;
    Ok(Json(SensorTypeList {
        items: state.store.sensor_types().await?,
    }))
}

/// `GET /v1/sensor-types/{type_id}`.
#[utoipa::path(
    get,
    path = "/v1/sensor-types/{type_id}",
    tag = "sensor-types",
    operation_id = "getSensorType",
    summary = "One sensor type.",
    params(("type_id" = crate::domain::schema::Identifier, Path, description = "The type's id.")),
    responses(
        (status = 200, description = "The type.", body = SensorType, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(type_id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    if check_str(&type_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(unknown_type(&type_id));
    }
    state
        .store
        .sensor_type(type_id.clone())
        .await?
        .map(|t| tagged(StatusCode::OK, &etag(&t), t))
        .ok_or_else(|| unknown_type(&type_id))
}
