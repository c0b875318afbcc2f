//! Reference standards: `PUT` (admin), and reading them (issue 29).

use axum::Json;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use serde::Serialize;
use utoipa::ToSchema;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::problem::Problem;
use crate::domain::audit::Actor;
use crate::domain::auth::{Principal, Role};
use crate::domain::limits::MAX_ID_CHARS;
use crate::domain::standards::{Standard, StandardBody};
use crate::domain::text::{Chars, check_str, echo};
use crate::domain::timestamp::Timestamp;

fn unknown_standard(standard_id: &str) -> Problem {
    Problem::not_found(format!("no standard `{}`", echo(standard_id)))
}

/// `PUT /v1/standards/{standard_id}` (admin): creates (201) or replaces
/// (200) a standard — a recalibration of it is a replacement with the new
/// certificate and due date; the certificate it replaces is kept among the
/// standard's `earlier` ones, so tests performed under it still pass.
#[utoipa::path(
    put,
    path = "/v1/standards/{standard_id}",
    tag = "standards",
    operation_id = "putStandard",
    summary = "Create or replace a reference standard (admin).",
    params(("standard_id" = crate::domain::schema::Identifier, Path, description = "The standard's id.")),
    request_body(content((StandardBody = "application/json",
        example = json!({"kind": "tumble_stand", "description": "Two-axis dividing head", "serial": "SN-4411",
            "certificate": {"number": "CAL-2026-0117", "issued_by": "National Metrology Laboratory", "calibrated_at": "2026-01-17T00:00:00Z"},
            "due_at": "2027-01-17T00:00:00Z", "angle_std_arcsec": 2.5,
            "traceability": "Angle traceable to the SI through the laboratory's autocollimator (CAL-2026-0117)."})))),
    responses(
        (status = 200, description = "Replaced.", body = Standard),
        (status = 201, description = "Created.", body = Standard),
        (status = 403, response = super::openapi::Forbidden),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn put(
    State(state): State<AppState>,
    principal: Principal,
    Path(standard_id): Path<String>,
    body: Body,
) -> Result<(StatusCode, Json<Standard>), Problem> {
    require(&principal, Role::Admin)?;
    if let Err(why) = check_str(&standard_id, MAX_ID_CHARS, Chars::Identifier) {
        return Err(Problem::bad_request(format!("the standard id {why}")));
    }
    let s = body
        .json::<StandardBody>()?
        .check(standard_id, Timestamp::now())?;
    let before = state.store.standard(s.standard_id.clone()).await?;
    let s = s.replacing(before);
    let created = state
        .store
        .put_standard(s.clone(), Actor::from(&principal))
        .await?;
    tracing::info!(standard = %s.standard_id, created, by = %principal.id, "standard written");
    let status = if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(s)))
}

/// A list of reference standards.
#[derive(Debug, Serialize, ToSchema)]
pub struct StandardList {
    /// Every standard, in id order.
    items: Vec<Standard>,
}

/// `GET /v1/standards`.
#[utoipa::path(
    get,
    path = "/v1/standards",
    tag = "standards",
    operation_id = "listStandards",
    summary = "Every reference standard.",
    responses(
        (status = 200, description = "The standards.", body = StandardList),
        super::openapi::Always,
    )
)]
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
) -> Result<Json<StandardList>, Problem> {
    require(&principal, Role::Reader)?;
    Ok(Json(StandardList {
        items: state.store.standards().await?,
    }))
}

/// `GET /v1/standards/{standard_id}`.
#[utoipa::path(
    get,
    path = "/v1/standards/{standard_id}",
    tag = "standards",
    operation_id = "getStandard",
    summary = "One reference standard.",
    params(("standard_id" = crate::domain::schema::Identifier, Path, description = "The standard's id.")),
    responses(
        (status = 200, description = "The standard.", body = Standard),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(standard_id): Path<String>,
) -> Result<Json<Standard>, Problem> {
    require(&principal, Role::Reader)?;
    if check_str(&standard_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(unknown_standard(&standard_id));
    }
    state
        .store
        .standard(standard_id.clone())
        .await?
        .map(Json)
        .ok_or_else(|| unknown_standard(&standard_id))
}
