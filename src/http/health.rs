//! Probes, the OpenAPI document and the fallback.

use axum::Json;
use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;
use serde::Serialize;
use utoipa::ToSchema;

use super::AppState;
use super::problem::Problem;

/// The answer of a probe.
#[derive(Serialize, ToSchema)]
pub struct Status {
    /// `ok` or `ready`.
    status: &'static str,
}

/// `GET /healthz`: the process is up.
#[utoipa::path(
    get,
    path = "/healthz",
    tag = "health",
    operation_id = "healthz",
    summary = "The process is up.",
    security(()),
    responses(
        (status = 200, description = "Up.", body = Status),
        (status = "default", response = super::openapi::ProblemResponse),
    )
)]
pub async fn healthz() -> Json<Status> {
    Json(Status { status: "ok" })
}

/// `GET /readyz`: the database answers and the server can take work.
#[utoipa::path(
    get,
    path = "/readyz",
    tag = "health",
    operation_id = "readyz",
    summary = "The database answers and the server has room for more requests.",
    security(()),
    responses(
        (status = 200, description = "Ready.", body = Status),
        (status = 503, response = super::openapi::Unavailable),
        (status = "default", response = super::openapi::ProblemResponse),
    )
)]
pub async fn readyz(State(state): State<AppState>) -> Result<Json<Status>, Problem> {
    if let Some(why) = state.admission.saturated() {
        return Err(Problem::unavailable(format!("at capacity: {why}"), 1));
    }
    state.store.ping().await?;
    Ok(Json(Status { status: "ready" }))
}

/// `GET /openapi.yaml`.
#[utoipa::path(
    get,
    path = "/openapi.yaml",
    tag = "health",
    operation_id = "openapi",
    summary = "This document.",
    security(()),
    responses(
        (status = 200, description = "The OpenAPI document.", content((serde_json::Value = "application/yaml"))),
        (status = "default", response = super::openapi::ProblemResponse),
    )
)]
pub async fn openapi() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "application/yaml")],
        super::openapi::OPENAPI.as_str(),
    )
}

/// Any other path.
pub async fn not_found() -> Problem {
    Problem::not_found("no such resource; see /openapi.yaml")
}
