//! `POST /v1/calibrations`, `POST /v1/calibrations/thermal` and reading
//! calibrations back.

use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use uuid::Uuid;

use super::auth::require;
use super::body::Body;
use super::problem::Problem;
use super::query::Params;
use super::stored::{created, idempotency_key};
use super::ui::dcc::prefers_xml;
use super::ui::issue;
use super::{AppState, path_id};
use crate::app::{Kind, submit};
use crate::domain::auth::{Principal, Role};
use crate::domain::thermal::ThermalParams;

/// `POST /v1/calibrations`: check, identify, fuse, store durably, answer 201;
/// with an `Idempotency-Key`, at most once per key.
#[utoipa::path(
    post,
    path = "/v1/calibrations",
    tag = "calibrations",
    operation_id = "submitCalibration",
    description = include_str!("docs/submit.md"),
    params(super::openapi::IdempotencyKeyHeader),
    request_body(content(
        (super::openapi::SubmissionSchema = "application/json"),
        (super::openapi::RawBodySchema = "text/csv"),
    )),
    responses(
        (status = 201, description = "Stored (or, for a retried Idempotency-Key, stored before).",
            body = super::openapi::StoredCalibrationSchema,
            headers(
                ("Location" = String, description = "The calibration's URL."),
                ("Idempotent-Replayed" = String, description = "`true` when this answer replays an earlier request with the same key."),
            ),
            links(
                ("GetCalibration" = (operation_id = "getCalibration", parameters(("id" = "$response.body#/id")))),
                ("GetSubmission" = (operation_id = "getSubmission", parameters(("id" = "$response.body#/id")))),
                ("GetSensor" = (operation_id = "getSensor", parameters(("sensor_id" = "$response.body#/sensor_id")))),
            )),
        (status = 403, response = super::openapi::Forbidden),
        (status = 408, response = super::openapi::ProblemResponse),
        (status = 409, response = super::openapi::ProblemResponse),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn submit(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Station)?;
    let key = idempotency_key(&headers, &principal, &body, None)?;
    let submitted = submit::submit(&state.lab, &principal, body, key, Kind::SingleAxis).await?;
    Ok(created(submitted))
}

/// `POST /v1/calibrations/thermal`: a single axis tumbled at several
/// temperatures, its temperature model fitted and stored as one
/// calibration of its sensor; with an `Idempotency-Key`, at most once per
/// key.
#[utoipa::path(
    post,
    path = "/v1/calibrations/thermal",
    tag = "calibrations",
    operation_id = "submitThermalCalibration",
    summary = "Fit a single axis's coefficients over temperature and store the model.",
    description = "The body of `POST /v1/calibrations` (JSON or CSV), each run with its \
        `temperature_c` — or a JSON body naming stored single-axis calibrations of the sensor \
        by id (`calibrations`), each tumbled at its own temperature, whose runs are then fitted \
        as one submission and whose ids the model keeps (`from_calibrations`) — and the fit's \
        parameters of `POST /v1/identify/thermal`. The runs are \
        grouped into set points, each identified and fused, and every coefficient's polynomial \
        fitted; the model is stored as one calibration of the sensor whose `coefficients` are \
        the model at `T_ref`: history, stability, review and withdrawal follow, and \
        `GET /v1/sensors/{sensor_id}/coefficients?temperature_c=` and `/compensate` with \
        `temperature_c` evaluate it within its range. The sensor type in force (named, or the \
        sensor's) judges every limited coefficient at every set point and across the range \
        (`decision`, its worst the verdict). The standards named are resolved and recorded as \
        for any calibration; a thermometer's `temperature_std_c` enters every coefficient read \
        at a temperature as u_T · |dc/dT|. Its certificate and DCC list every polynomial's a_d.",
    params(super::openapi::IdempotencyKeyHeader, crate::domain::thermal::ThermalParams),
    request_body(content(
        (super::openapi::ThermalBodySchema = "application/json"),
        (super::openapi::RawBodySchema = "text/csv"),
    )),
    responses(
        (status = 201, description = "Stored (or, for a retried Idempotency-Key, stored before).",
            body = crate::app::thermal::StoredThermal,
            headers(
                ("Location" = String, description = "The calibration's URL."),
                ("Idempotent-Replayed" = String, description = "`true` when this answer replays an earlier request with the same key."),
            ),
            links(
                ("GetCalibration" = (operation_id = "getCalibration", parameters(("id" = "$response.body#/id")))),
                ("GetSensor" = (operation_id = "getSensor", parameters(("sensor_id" = "$response.body#/sensor_id")))),
            )),
        (status = 403, response = super::openapi::Forbidden),
        (status = 409, response = super::openapi::ProblemResponse),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn submit_thermal(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    Params(params): Params<ThermalParams>,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Station)?;
    let fit = params
        .checked()
        .map_err(|b| Problem::bad_parameter(b.name, b.detail))?;
    let fitted_with = serde_json::to_string(&fit.params).map_err(|_| Problem::internal())?;
    let key = idempotency_key(
        &headers,
        &principal,
        &body,
        Some(&format!("thermal {fitted_with}")),
    )?;
    let submitted = submit::submit(&state.lab, &principal, body, key, Kind::Thermal(fit)).await?;
    Ok(created(submitted))
}

fn unknown(id: Uuid) -> Problem {
    Problem::not_found(format!("no calibration with id `{id}`"))
}

/// `GET /v1/calibrations/{id}`: the stored result document, as stored.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}",
    tag = "calibrations",
    operation_id = "getCalibration",
    params(super::openapi::CalibrationIdPath),
    responses(
        (status = 200, description = "The result, as answered when it was submitted: a single-axis \
            calibration's, a triad's (`kind: triad`) or a temperature model's (`kind: thermal`).", body = super::openapi::StoredResultSchema),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    let result = state
        .store
        .calibration_result(id)
        .await?
        .ok_or_else(|| unknown(id))?;
    Ok(([(header::CONTENT_TYPE, "application/json")], result).into_response())
}

/// `GET /v1/calibrations/{id}/submission`: the body as submitted, byte for byte.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}/submission",
    tag = "calibrations",
    operation_id = "getSubmission",
    params(super::openapi::CalibrationIdPath),
    responses(
        (status = 200, description = "The body as submitted (decompressed, if it was sent gzip-encoded).",
            content((super::openapi::RawBodySchema = "text/csv"), (serde_json::Value = "application/json"))),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn submission(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    let s = state
        .store
        .submission(id)
        .await?
        .ok_or_else(|| unknown(id))?;
    let content_type = HeaderValue::from_str(&s.content_type)
        .unwrap_or(HeaderValue::from_static("application/octet-stream"));
    Ok(([(header::CONTENT_TYPE, content_type)], s.body).into_response())
}

/// The query of `GET /v1/calibrations/{id}/certificate`.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub struct CertificateQuery {
    /// The revision of the issued certificate to answer (1 as issued, 2 for
    /// the first amendment, …); the latest without.
    #[param(minimum = 1)]
    #[allow(dead_code)]
    revision: Option<u32>,
}

/// `GET /v1/calibrations/{id}/certificate`: the certificate as issued.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}/certificate",
    tag = "calibrations",
    operation_id = "getCertificate",
    summary = "The calibration certificate: an HTML document that prints on A4, or with \
        `Accept: application/xml` a Digital Calibration Certificate (PTB DCC 3.3.0).",
    description = "An approved calibration's certificate is issued with the approval and \
        answered as issued ever after — the DCC byte for byte — whatever changes later to the \
        item, the customer or the laboratory; changing it is an amendment \
        (`POST …/amend`), a new revision of the same number, and `?revision=N` answers any \
        revision (`Certificate-Revision` says which). A calibration withdrawn, superseded or \
        held since is answered with that notice before the issued document. One not \
        approved is rendered on request as a draft (`Certificate-Revision: draft`), and has \
        no DCC (409).",
    params(super::openapi::CalibrationIdPath, CertificateQuery),
    responses(
        (status = 200, description = "The certificate: sensor, type, station and stand, times, method, \
            fused coefficients with expanded uncertainty, decision, as found, due date, the SHA-256 of \
            the stored submission, the accelcal version and its own URL.",
            content((String = "text/html"), (String = "application/xml")),
            headers(("Certificate-Revision" = String, description = "The revision answered, or `draft`."))),
        (status = 400, response = super::openapi::BadRequest),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::Incomplete),
        super::openapi::Always,
    )
)]
pub async fn certificate(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    Path(id): Path<String>,
    RawQuery(query): RawQuery,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let revision = issue::revision(query.as_deref())?;
    let xml = prefers_xml(&headers);
    issue::respond(&state, &headers, &id, revision, xml).await
}
