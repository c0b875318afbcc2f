//! Computations that store nothing: `POST /v1/identify`, `POST
//! /v1/identify/thermal`, `POST /v1/identify/thermal/triad` and `POST
//! /v1/fuse`.

use accelcal_core::Estimates;
use axum::Json;
use axum::extract::{RawQuery, State};
use axum::response::{IntoResponse, Response};

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::problem::Problem;
use super::query::Params;
use crate::app::{single_axis, thermal};
use crate::domain::auth::{Principal, Role};
use crate::domain::fuse::FuseRequest;
use crate::domain::thermal::{ThermalModel, ThermalParams};
use crate::domain::timestamp::Timestamp;
use crate::domain::triad_export::Format;

/// `POST /v1/identify`: a submission computed and returned, not stored.
///
/// A station token bound to a station may name only that station, as on
/// submission.
#[utoipa::path(
    post,
    path = "/v1/identify",
    tag = "compute",
    operation_id = "identify",
    summary = "Compute a submission without storing it.",
    request_body(content(
        (super::openapi::SubmissionSchema = "application/json"),
        (String = "text/csv"),
    )),
    responses(
        (status = 200, description = "The result (without `id`).", body = super::openapi::CalibrationResultSchema),
        (status = 403, response = super::openapi::Forbidden),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn identify(
    State(state): State<AppState>,
    principal: Principal,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let assessed =
        single_axis::assess(&state.lab, &principal, body, Timestamp::now(), None, None).await?;
    Ok((
        [(axum::http::header::CONTENT_TYPE, "application/json")],
        assessed.result,
    )
        .into_response())
}

/// `POST /v1/identify/thermal`: a single axis's coefficients over
/// temperature, from a submission whose runs were made at several
/// temperatures (each run's `temperature_c`), computed and returned, not
/// stored.
#[utoipa::path(
    post,
    path = "/v1/identify/thermal",
    tag = "compute",
    operation_id = "identifyThermal",
    summary = "Coefficients over temperature from runs at several temperatures, not stored.",
    description = "The runs are grouped into set points (runs within `tolerance_k` of a set \
        point's coolest run), each set point identified and fused as a calibration is, and \
        every coefficient's polynomial c(T) = Σ a_d (T − T_ref)^d fitted by weighted least \
        squares on the set points' fused estimates (weights 1/se², covariance inflated by \
        max(1, χ²/ν)), its degree chosen by backward elimination at 1 % unless `degree` is \
        given. Too few set points, too small a span or an ill-conditioned design are refused \
        with what to add. The runs may instead be those of stored single-axis calibrations of \
        the sensor, named by id (`calibrations`), each tumbled at its own temperature.",
    params(crate::domain::thermal::ThermalParams),
    request_body(content(
        (super::openapi::ThermalBodySchema = "application/json"),
        (String = "text/csv"),
    )),
    responses(
        (status = 200, description = "The set points and each coefficient's polynomial.", body = super::openapi::ThermalModelSchema),
        (status = 403, response = super::openapi::Forbidden),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn identify_thermal(
    State(state): State<AppState>,
    principal: Principal,
    Params(params): Params<ThermalParams>,
    body: Body,
) -> Result<Json<ThermalModel>, Problem> {
    require(&principal, Role::Reader)?;
    let fit = params
        .checked()
        .map_err(|b| Problem::bad_parameter(b.name, b.detail))?;
    Ok(Json(
        thermal::identify(&state.lab, &principal, body, fit).await?,
    ))
}

/// `POST /v1/identify/thermal/triad`: a triad's `b` and `S` over
/// temperature, from runs with known orientations made at several
/// temperatures, computed and returned, not stored.
#[utoipa::path(
    post,
    path = "/v1/identify/thermal/triad",
    tag = "compute",
    operation_id = "identifyThermalTriad",
    summary = "A triad's b and S over temperature from runs at several temperatures, not stored.",
    description = "A triad body with known `orientations` and `runs`, each run with its \
        `temperature_c` (or one per position); or `static_positions` with \
        `static_temperatures_c`, or a `recording` with each sample's `temperature_c` (each set \
        point fitted from the gravity magnitude; S_xy, S_xz, S_yz zero by convention). The runs \
        are grouped into set points as for a single axis, each set \
        point calibrated and fused as a triad is, and every element of b and S given its \
        polynomial e(T) = Σ a_d (T − T_ref)^d, fitted by weighted least squares on the set \
        points' fused elements (weights 1/se², covariance inflated by max(1, χ²/ν)), its degree \
        chosen by backward elimination at 1 % unless `degree` is given. Too few set points, too \
        small a span or an ill-conditioned design are refused with what to add. Standards \
        named are resolved (a thermometer's uncertainty enters the elements); a sensor type \
        judges a model when it is stored, and is refused here. Or name two to 64 stored \
        triad calibrations of the sensor, each at one temperature (`{sensor_id, \
        calibrations}`): their stored bodies make one.",
    params(crate::domain::thermal::ThermalParams, ThermalExportQuery),
    request_body(content((super::openapi::TriadThermalBodySchema = "application/json"))),
    responses(
        (status = 200, description = "The set points and each element's polynomial; with \
            `export`, the file asked for.",
            content((super::openapi::TriadThermalModelSchema = "application/json"), (String = "text/plain"), (String = "text/x-c"))),
        (status = 409, response = super::openapi::NotCarried),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn identify_thermal_triad(
    State(state): State<AppState>,
    principal: Principal,
    RawQuery(query): RawQuery,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let (params, export) =
        super::query::parse_but::<ThermalParams>(query.as_deref().unwrap_or_default(), "export")?;
    let format = export
        .as_deref()
        .map(|e| {
            Format::parse(e).ok_or_else(|| {
                Problem::bad_parameter("export", "must be json, c, px4 or ardupilot")
            })
        })
        .transpose()?;
    let fit = params
        .checked()
        .map_err(|b| Problem::bad_parameter(b.name, b.detail))?;
    let model = thermal::identify_triad(&state.lab, &principal, body, fit).await?;
    let Some(format) = format else {
        return Ok(Json(model).into_response());
    };
    let source = format!(
        "triad {}, computed by accelcal {}",
        model.sensor_id.as_deref().unwrap_or("(no sensor_id)"),
        env!("CARGO_PKG_VERSION")
    );
    super::firmware::thermal_file(&model, format, &source)
}

/// The query `POST /v1/identify/thermal/triad` adds to the fit's.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub struct ThermalExportQuery {
    /// Answer a file instead of the model: `json` (the model), `c` (a C
    /// header of every polynomial), `px4` (PX4's `TC_A0_*`) or
    /// `ardupilot` (ArduPilot's `INS_TCAL1_*` with the offsets at their
    /// calibration temperature). PX4 and ArduPilot carry the offset's
    /// polynomial only: when an element of S changes over the range by
    /// more than its expanded uncertainty they are refused with 409
    /// `not-carried`.
    #[param(pattern = "^(json|c|px4|ardupilot)$")]
    pub export: Option<String>,
}

/// `POST /v1/fuse`: mean and batch-estimation fusion of given per-run values
/// (how the paper's Table 2 is reproduced).
#[utoipa::path(
    post,
    path = "/v1/fuse",
    tag = "compute",
    operation_id = "fuse",
    summary = "Mean and batch-estimation fusion of given per-run values.",
    description = "The fusion applied to per-run coefficients the caller supplies (how \
        the paper's Table 2 is reproduced). Every term needs the same number \
        of values, at least two per batch.",
    request_body(content((FuseRequest = "application/json",
        example = json!({"values": {"k0": [-0.0008222, -0.0008709, -0.0008703, -0.0008426, -0.0008339, -0.0008544]}, "batches": 2})))),
    responses(
        (status = 200, description = "Mean and fused estimates.", body = super::openapi::EstimatesSchema),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn fuse(
    State(_): State<AppState>,
    principal: Principal,
    body: Body,
) -> Result<Json<Estimates>, Problem> {
    require(&principal, Role::Reader)?;
    let request: FuseRequest = body.json()?;
    Ok(Json(request.fuse()?))
}
