//! `POST /v1/identify/triad`: a triad calibrated and answered, not stored
//! (issue 30) — from known orientations, from static positions of unknown
//! orientation, or from one continuous recording — and, with `?export=`,
//! the result in the form firmware loads.

use axum::extract::State;
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use utoipa::IntoParams;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::firmware::{TriadExport, file};
use super::problem::Problem;
use super::query::Params;
use crate::app::triad;
use crate::domain::auth::{Principal, Role};
use crate::domain::triad::{TriadBody, TriadResult};
use crate::domain::triad_export::{Exported, Format};

/// The query of `POST /v1/identify/triad`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct TriadQuery {
    /// Answer the calibration as `json` (b, S, T and the convention), `c`
    /// (a header), `px4` or `ardupilot` (parameter files) instead of the
    /// full result.
    #[param(pattern = "^(json|c|px4|ardupilot)$")]
    pub export: Option<String>,
}

/// A JSON answer: the result, or with `export=json` the export.
#[derive(serde::Serialize, utoipa::ToSchema)]
#[serde(untagged)]
pub enum TriadJson {
    /// Without `export`.
    Result(Box<TriadResult>),
    /// With `export=json`.
    Export(Box<TriadExport>),
}

/// `POST /v1/identify/triad`.
#[utoipa::path(
    post,
    path = "/v1/identify/triad",
    tag = "compute",
    operation_id = "identifyTriad",
    summary = "Calibrate a triad (u = b + S g) without storing it.",
    description = "Exactly one of: `orientations` (gravity vectors in g, `six_faces` or `cube24`) with \
        `runs` — each axis identified and fused by the single-axis method; `static_positions` (at least \
        nine) — b and T = S⁻¹ from the gravity magnitude by Levenberg–Marquardt; `recording` — its \
        static intervals as the positions. As CSV: the header `u_x,u_y,u_z` (a recording, `# rate_hz:` \
        before it), `position,u_x,u_y,u_z` or `run,g_x,g_y,g_z,u_x,u_y,u_z`. With `export`, the \
        calibration as a file.",
    params(TriadQuery),
    request_body(content((String = "text/csv"), (TriadBody = "application/json",
        example = json!({"unit": "m/s2", "orientations": "six_faces", "runs": [{"samples": [
            [[9.91, 0.02, -0.05]], [[-9.71, 0.01, -0.06]], [[0.12, 9.79, -0.04]],
            [[0.09, -9.83, -0.07]], [[0.11, 0.03, 9.75]], [[0.10, 0.00, -9.87]]]}]})))),
    responses(
        (status = 200, description = "The triad's b, S, T with standard errors, scale factors, \
            non-orthogonality, residuals, and the fit or the single-axis results; with `export`, the file.",
            content((TriadJson = "application/json"), (String = "text/plain"), (String = "text/x-c"))),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn identify(
    State(state): State<AppState>,
    principal: Principal,
    Params(q): Params<TriadQuery>,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let format = export_format(q.export.as_deref())?;
    let result = triad::identify(&state.lab, body).await?;
    let Some(format) = format else {
        return Ok(axum::Json(result).into_response());
    };
    let source = match &result.sensor_id {
        Some(s) => format!(
            "triad {s}, computed by accelcal {}",
            env!("CARGO_PKG_VERSION")
        ),
        None => format!("a triad computed by accelcal {}", env!("CARGO_PKG_VERSION")),
    };
    file(
        &Exported {
            unit: &result.unit,
            b: result.b,
            s: result.s,
            t: result.t,
            s2: result.s2,
            source,
        },
        format,
    )
}

/// The `export` parameter read: `None` when absent.
pub(super) fn export_format(export: Option<&str>) -> Result<Option<Format>, Problem> {
    export
        .map(|f| {
            Format::parse(f).ok_or_else(|| {
                Problem::bad_parameter("export", "must be json, c, px4 or ardupilot")
            })
        })
        .transpose()
}
