//! Reference standards: `PUT` (admin), reading them, and their
//! nonconformities with the calibrations they concern (issue 29).

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
use crate::app::{definitions, hold};
use crate::domain::auth::{Principal, Role};
use crate::domain::limits::MAX_ID_CHARS;
use crate::domain::nonconformity::{NonconformityBody, Traced};
use crate::domain::standards::{Standard, StandardBody};
use crate::domain::text::{Chars, check_str};
use crate::domain::timestamp::Timestamp;
use crate::store::conditional::etag;

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
    params(("standard_id" = crate::domain::schema::Identifier, Path, description = "The standard's id."),
        super::openapi::ConditionalHeaders),
    request_body(content((StandardBody = "application/json",
        example = json!({"kind": "tumble_stand", "description": "Two-axis dividing head", "serial": "SN-4411",
            "certificate": {"number": "CAL-2026-0117", "issued_by": "National Metrology Laboratory", "calibrated_at": "2026-01-17T00:00:00Z"},
            "due_at": "2027-01-17T00:00:00Z", "angle_std_arcsec": 2.5,
            "traceability": "Angle traceable to the SI through the laboratory's autocollimator (CAL-2026-0117)."})))),
    responses(
        (status = 200, description = "Replaced.", body = Standard, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 201, description = "Created.", body = Standard, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 403, response = super::openapi::Forbidden),
        (status = 412, response = super::openapi::PreconditionFailed),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn put(
    State(state): State<AppState>,
    principal: Principal,
    Path(standard_id): Path<String>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Admin)?;
    if let Err(why) = check_str(&standard_id, MAX_ID_CHARS, Chars::Identifier) {
        return Err(Problem::bad_request(format!("the standard id {why}")));
    }
    let pre = precondition(&headers)?;
    let s = body
        .json::<StandardBody>()?
        .check(standard_id, Timestamp::now())?;
    written(
        definitions::standard(&state.lab, &principal, s, pre).await?,
        "standard",
    )
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
        (status = 200, description = "The standard.", body = Standard, headers(("ETag" = String, description = "The record's entity tag, for If-Match."))),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(standard_id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let s = hold::known(&state.lab, &standard_id).await?;
    Ok(tagged(StatusCode::OK, &etag(&s), s))
}

/// A standard's nonconformities and the calibrations each concerns.
#[derive(Debug, Serialize, ToSchema)]
pub struct AffectedList {
    /// The standard.
    standard_id: String,
    /// Its nonconformities, oldest `found_at` first.
    nonconformities: Vec<Traced>,
}

/// `POST /v1/standards/{standard_id}/nonconformity` (admin): the standard
/// was found nonconforming; every calibration made with it in the affected
/// window that counts is placed under review (a `hold` signature), and its
/// coefficients stop being usable until a reviewer approves it again or
/// withdraws it (reverse trace, issue 29 item 3).
#[utoipa::path(
    post,
    path = "/v1/standards/{standard_id}/nonconformity",
    tag = "standards",
    operation_id = "recordNonconformity",
    summary = "Record that a standard was found nonconforming, and hold what it spoiled (admin).",
    params(("standard_id" = crate::domain::schema::Identifier, Path, description = "The standard's id.")),
    request_body(content((NonconformityBody = "application/json",
        example = json!({"found_at": "2026-11-20T09:00:00Z",
            "reason": "Indexing error of 9″ found at the 90° stop in the annual check."})))),
    responses(
        (status = 201, description = "Recorded; the calibrations of the window, each with what became of it.", body = Traced),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn nonconformity(
    State(state): State<AppState>,
    principal: Principal,
    Path(standard_id): Path<String>,
    body: Body,
) -> Result<(StatusCode, Json<Traced>), Problem> {
    require(&principal, Role::Admin)?;
    let standard = hold::known(&state.lab, &standard_id).await?;
    let found = body.json::<NonconformityBody>()?;
    let traced = hold::nonconformity(&state.lab, &principal, &standard, found).await?;
    Ok((StatusCode::CREATED, Json(traced)))
}

/// `GET /v1/standards/{standard_id}/affected`: every nonconformity of the
/// standard, each with the calibrations of its window, their sensors, and
/// what became of each (still under review, approved again, withdrawn,
/// superseded, or left as it was).
#[utoipa::path(
    get,
    path = "/v1/standards/{standard_id}/affected",
    tag = "standards",
    operation_id = "listAffected",
    summary = "The calibrations a standard's nonconformities concern.",
    params(("standard_id" = crate::domain::schema::Identifier, Path, description = "The standard's id.")),
    responses(
        (status = 200, description = "Its nonconformities, oldest first.", body = AffectedList),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn affected(
    State(state): State<AppState>,
    principal: Principal,
    Path(standard_id): Path<String>,
) -> Result<Json<AffectedList>, Problem> {
    require(&principal, Role::Reader)?;
    hold::known(&state.lab, &standard_id).await?;
    let nonconformities = state.store.nonconformities(standard_id.clone()).await?;
    Ok(Json(AffectedList {
        standard_id,
        nonconformities,
    }))
}
