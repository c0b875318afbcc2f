//! A stored or computed triad as the file firmware loads (`json`, `c`,
//! `px4`, `ardupilot`): what the export route, the identify route's
//! `?export=` and the triad page's downloads answer — for a triad's
//! temperature model, its thermal parameters ([`thermal_file`]).

use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use uuid::Uuid;

use super::AppState;
use super::problem::{Kind, Problem};
use crate::domain::field::Invalid;
use crate::domain::review::Basis;
use crate::domain::text::echo;
use crate::domain::triad_export::{Exported, Format, export};

/// The `json` export's document (schema only: `triad_export` writes it).
#[derive(serde::Serialize, utoipa::ToSchema)]
pub struct TriadExport {
    /// What it describes.
    pub source: String,
    /// `u = b + S g`.
    model: String,
    /// `g = T (u - b), T = S^-1`.
    compensation: String,
    /// The convention in words.
    convention: String,
    /// The outputs' unit.
    unit: String,
    /// The units of `b`, `S` and `T`.
    units: TriadExportUnits,
    /// `b`.
    b: [f64; 3],
    /// `S`, by rows.
    #[serde(rename = "S")]
    s: [[f64; 3]; 3],
    /// `T = S⁻¹`, by rows.
    #[serde(rename = "T")]
    t: [[f64; 3]; 3],
}

/// The units of the `json` export's `b`, `S` and `T`.
#[derive(serde::Serialize, utoipa::ToSchema)]
pub struct TriadExportUnits {
    /// `b`'s.
    b: String,
    /// `S`'s.
    #[serde(rename = "S")]
    s: String,
    /// `T`'s.
    #[serde(rename = "T")]
    t: String,
}

/// `e` as a file in `format`, named for download; a format that cannot
/// carry it is a 422 saying what it would drop.
pub fn file(e: &Exported<'_>, format: Format) -> Result<Response, Problem> {
    let file =
        export(e, format).map_err(|e| Problem::validation(Invalid::one("", e.to_string())))?;
    Ok(attachment(file, format.media_type(), format.file_name()))
}

/// The triad's temperature `model` as a file in `format`, described by
/// `source`: outputs PX4 or ArduPilot cannot take are a 422 naming
/// `/unit`, a scale factor they cannot carry a 409 `not-carried`.
pub fn thermal_file(
    model: &crate::domain::thermal::TriadThermalModel,
    format: Format,
    source: &str,
) -> Result<Response, Problem> {
    use crate::domain::thermal::firmware::ThermalExportError;
    let file = crate::domain::thermal::export(model, format, source).map_err(|e| match e {
        ThermalExportError::Unit(e) => Problem::validation(Invalid::one("/unit", e.to_string())),
        e @ ThermalExportError::NotCarried { .. } => Problem::new(Kind::NotCarried, e.to_string()),
    })?;
    Ok(attachment(
        file,
        format.media_type(),
        crate::domain::thermal::file_name(format),
    ))
}

/// `body` answered as a download of type `media` named `name`.
pub fn attachment(body: String, media: &'static str, name: &'static str) -> Response {
    let mut res = body.into_response();
    let h = res.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(media));
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{name}\"")) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    res
}

/// Calibration `id` as a firmware file in `format` (what the export route
/// and the page's download answer).
pub async fn exported(state: &AppState, id: Uuid, format: &str) -> Result<Response, Problem> {
    let format = Format::parse(format)
        .ok_or_else(|| Problem::bad_parameter("format", "must be json, c, px4 or ardupilot"))?;
    let c = state
        .store
        .calibration_summary(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    let Some(t) = &c.triad else {
        return Err(Problem::new(
            Kind::WrongKind,
            format!(
                "calibration {id} is single-axis: its coefficients are at \
                 GET /v1/calibrations/{id}; exports are for triads"
            ),
        ));
    };
    if !c.state.counts(Basis::NotRejected) {
        return Err(Problem::new(
            Kind::StateConflict,
            format!(
                "calibration {id} is {}: it no longer counts and is not exported; the sensor's \
                 latest is at GET /v1/sensors/{}",
                c.state.as_str(),
                echo(&c.sensor_id)
            ),
        ));
    }
    let source = format!(
        "triad {}, calibration {id} performed {} ({}), accelcal {}",
        c.sensor_id,
        c.performed_at,
        c.state.as_str(),
        env!("CARGO_PKG_VERSION")
    );
    // A temperature model exports its polynomials, not one temperature's.
    if let Some(model) = &c.thermal_triad {
        return thermal_file(model, format, &format!("temperature model of {source}"));
    }
    file(
        &Exported {
            unit: &c.unit,
            b: t.b,
            s: t.s,
            t: t.t,
            s2: t.s2,
            source,
        },
        format,
    )
}
