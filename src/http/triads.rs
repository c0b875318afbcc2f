//! Stored triad calibrations (issue 30): `POST /v1/calibrations/triad`
//! stores a triad as the triad kind computes it ([`crate::app::triad`]),
//! `POST /v1/calibrations/thermal/triad` a triad's temperature model
//! ([`crate::app::thermal::triad`]), and `GET /v1/calibrations/{id}/export`
//! answers a stored triad in the form firmware loads ([`super::firmware`]).

use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::Response;
use serde::Deserialize;
use utoipa::IntoParams;

use super::auth::require;
use super::body::Body;
use super::firmware::exported;
use super::problem::Problem;
use super::query::Params;
use super::stored::{created, idempotency_key};
use super::{AppState, path_id};
use crate::app::{Kind, submit};
use crate::domain::auth::{Principal, Role};

/// `POST /v1/calibrations/thermal/triad`: a triad tumbled at several
/// temperatures, its model fitted and stored as one calibration of the
/// triad; with an `Idempotency-Key`, at most once per key.
#[utoipa::path(
    post,
    path = "/v1/calibrations/thermal/triad",
    tag = "calibrations",
    operation_id = "submitThermalTriad",
    summary = "Fit a triad's b and S over temperature and store the model.",
    description = "The body of `POST /v1/identify/thermal/triad` (known `orientations`, every \
        run with its `temperature_c`; or static positions or a recording with their \
        temperatures) with `sensor_id`, and the same fit parameters. Stored as \
        one calibration of the triad whose elements (`elements`: b, S, T = S⁻¹) are the model \
        at `T_ref`: history, stability and the coefficients without a temperature serve them; \
        `GET /v1/sensors/{sensor_id}/coefficients?temperature_c=` and `/compensate` with \
        `temperature_c` evaluate the model within its range, and \
        `GET /v1/calibrations/{id}/export` answers its thermal parameters (PX4's `TC_A0_*`, \
        ArduPilot's `INS_TCAL1_*`, a C header, the model). The sensor type in force (named, \
        or the triad's) judges every limited element at every set point and across the range \
        (`decision`); the standards named are resolved and recorded, a thermometer's \
        uncertainty entering every element read at a temperature; the certificate and DCC are \
        issued at approval as for any calibration. Or name two to 64 stored triad \
        calibrations of the sensor, each at one temperature (`{sensor_id, calibrations}`): \
        their stored bodies make one, fitted as one sent whole, and the model lists them \
        (`from_calibrations`).",
    params(super::openapi::IdempotencyKeyHeader, crate::domain::thermal::ThermalParams),
    request_body(content((super::openapi::TriadThermalBodySchema = "application/json"), (String = "text/csv"))),
    responses(
        (status = 201, description = "Stored (or, for a retried Idempotency-Key, stored before).",
            body = crate::app::thermal::triad::StoredThermalTriad,
            headers(
                ("Location" = String, description = "The calibration's URL."),
                ("Idempotent-Replayed" = String, description = "`true` when this answer replays an earlier request with the same key."),
            ),
            links(
                ("GetCalibration" = (operation_id = "getCalibration", parameters(("id" = "$response.body#/id")))),
                ("ExportCalibration" = (operation_id = "exportCalibration", parameters(("id" = "$response.body#/id")))),
            )),
        (status = 403, response = super::openapi::Forbidden),
        (status = 409, response = super::openapi::WrongKind),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn submit_thermal(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    Params(params): Params<crate::domain::thermal::ThermalParams>,
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
        Some(&format!("thermal-triad {fitted_with}")),
    )?;
    let submitted =
        submit::submit(&state.lab, &principal, body, key, Kind::ThermalTriad(fit)).await?;
    Ok(created(submitted))
}

/// `POST /v1/calibrations/triad`: check, compute, store durably, answer 201;
/// with an `Idempotency-Key`, at most once per key.
#[utoipa::path(
    post,
    path = "/v1/calibrations/triad",
    tag = "calibrations",
    operation_id = "submitTriad",
    summary = "Calibrate a triad (u = b + S g) and store it as a calibration of its sensor.",
    description = "The body of `POST /v1/identify/triad` (JSON or CSV) with `sensor_id` \
        required and, optionally, `station_id` and `performed_at` (CSV: `# key: value` lines). \
        Stored as one calibration of the sensor: its history, review, withdrawal, compensation \
        with triples and the firmware exports (`GET /v1/calibrations/{id}/export`) follow. A \
        sensor's calibrations are all single-axis or all a triad's (409 `wrong-kind`).",
    params(super::openapi::IdempotencyKeyHeader),
    request_body(content((String = "text/csv"), (crate::domain::triad::TriadBody = "application/json",
        example = json!({"sensor_id": "IMU-7", "unit": "m/s2", "orientations": "six_faces",
            "runs": [{"samples": [
            [[9.91, 0.02, -0.05]], [[-9.71, 0.01, -0.06]], [[0.12, 9.79, -0.04]],
            [[0.09, -9.83, -0.07]], [[0.11, 0.03, 9.75]], [[0.10, 0.00, -9.87]]]}]})))),
    responses(
        (status = 201, description = "Stored (or, for a retried Idempotency-Key, stored before).",
            body = crate::app::triad::StoredTriad,
            headers(
                ("Location" = String, description = "The calibration's URL."),
                ("Idempotent-Replayed" = String, description = "`true` when this answer replays an earlier request with the same key."),
            ),
            links(
                ("GetCalibration" = (operation_id = "getCalibration", parameters(("id" = "$response.body#/id")))),
                ("ExportCalibration" = (operation_id = "exportCalibration", parameters(("id" = "$response.body#/id")))),
            )),
        (status = 403, response = super::openapi::Forbidden),
        (status = 409, response = super::openapi::WrongKind),
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
    let key = idempotency_key(&headers, &principal, &body, Some("triad"))?;
    let submitted = submit::submit(&state.lab, &principal, body, key, Kind::Triad).await?;
    Ok(created(submitted))
}

/// The query of `GET /v1/calibrations/{id}/export`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ExportQuery {
    /// `json` (b, S, T and the convention), `c` (a header), `px4` or
    /// `ardupilot` (parameter files).
    #[param(pattern = "^(json|c|px4|ardupilot)$")]
    pub format: String,
}

/// `GET /v1/calibrations/{id}/export?format=…`: a stored triad as a file.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}/export",
    tag = "calibrations",
    operation_id = "exportCalibration",
    summary = "A stored triad in the form firmware loads.",
    description = "`json` (b, S, T, the model and convention, units), `c` (a header with the \
        arrays and the equation in a comment), `px4` (`CAL_ACC0_*OFF`, `CAL_ACC0_*SCALE`) or \
        `ardupilot` (`INS_ACCOFFS_*`, `INS_ACCSCAL_*`). PX4 and ArduPilot carry only a diagonal: \
        an off-diagonal term of T above 1 % of its row's diagonal is refused (422), a smaller \
        one named in the file; both need outputs in m/s² or g. A calibration that no longer \
        counts (rejected, withdrawn, superseded) is not exported (409); a single-axis one has \
        no export (409 `wrong-kind`). A triad's temperature model (`POST \
        /v1/calibrations/thermal/triad`) exports its polynomials instead: PX4's `TC_A0_*`, \
        ArduPilot's `INS_TCAL1_*`, a C header of every polynomial, or the model — PX4 and \
        ArduPilot refused with 409 `not-carried` when an element of S changes over the range by \
        more than its expanded uncertainty.",
    params(super::openapi::CalibrationIdPath, ExportQuery),
    responses(
        (status = 200, description = "The file, named for download.",
            content((super::firmware::TriadExport = "application/json"), (String = "text/plain"), (String = "text/x-c"))),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::WrongKind),
        super::openapi::Always,
        (status = 422, response = super::openapi::Invalid),
    )
)]
pub async fn export(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
    Params(q): Params<ExportQuery>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    exported(&state, id, &q.format).await
}
