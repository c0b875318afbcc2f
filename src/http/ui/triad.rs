//! `GET /ui/calibrations/{id}` for a triad's calibration (issue 30): `b`,
//! `S` and `T` with their standard errors, the scale factors and
//! non-orthogonality, the fit (unknown orientations) and the residuals per
//! position, the firmware files to download
//! (`GET /ui/calibrations/{id}/export/{format}`), and the review as for any
//! calibration. What it reads is the stored result document ([`TriadDoc`]).

use axum::extract::{Path, State};
use axum::response::Response;
use maud::{Markup, html};
use serde::Deserialize;

use super::calibration::{record, when};
use super::format::{num, opt, unc};
use super::session::Viewer;
use super::{Html, UiError, layout, review};
use crate::http::{AppState, path_id};
use crate::store::AXES;

/// A stored triad's result document, as the page reads it.
#[derive(Debug, Clone, Deserialize)]
pub struct TriadDoc {
    /// The calibration.
    pub id: uuid::Uuid,
    /// The triad.
    pub sensor_id: String,
    /// The station.
    pub station_id: Option<String>,
    /// When performed.
    pub performed_at: String,
    /// When received.
    pub received_at: String,
    /// `known_orientations` or `gravity_magnitude`.
    pub method: String,
    /// The outputs' unit.
    pub unit: String,
    /// `b`.
    pub b: [f64; 3],
    /// Its standard errors.
    pub b_std_errors: Option<[f64; 3]>,
    /// `S`.
    #[serde(rename = "S")]
    pub s: [[f64; 3]; 3],
    /// Its standard errors.
    #[serde(rename = "S_std_errors", default)]
    pub s_std_errors: Option<[[f64; 3]; 3]>,
    /// `T = S⁻¹`.
    #[serde(rename = "T")]
    pub t: [[f64; 3]; 3],
    /// Its standard errors.
    #[serde(rename = "T_std_errors", default)]
    pub t_std_errors: Option<[[f64; 3]; 3]>,
    /// Row norms of `S`.
    pub scale_factors: [f64; 3],
    /// xy, yz, zx.
    pub non_orthogonality_deg: [f64; 3],
    /// Per position.
    pub residuals: Vec<Vec<f64>>,
    /// The fit (unknown orientations).
    #[serde(default)]
    pub fit: Option<FitDoc>,
}

/// The Levenberg–Marquardt fit's report.
#[derive(Debug, Clone, Deserialize)]
pub struct FitDoc {
    /// Evaluations.
    pub evaluations: usize,
    /// Why it stopped.
    pub stop: String,
    /// The directions' spread.
    pub spread: f64,
    /// Residuals' RMS, g.
    pub rms_g: f64,
}

/// The firmware files offered, with their labels.
const EXPORTS: [(&str, &str); 4] = [
    ("json", "JSON"),
    ("c", "C header"),
    ("px4", "PX4 parameters"),
    ("ardupilot", "ArduPilot parameters"),
];

/// A vector (or a matrix's rows) with standard errors beside each value.
fn vector(name: &str, v: &[f64; 3], e: Option<&[f64; 3]>) -> Markup {
    html! {
        tr {
            th scope="row" { (name) }
            @for (k, x) in v.iter().enumerate() {
                td.num { (num(*x)) }
                td.num { (opt(e.map(|e| e[k]), unc)) }
            }
        }
    }
}

fn matrix(caption: &str, name: &str, m: &[[f64; 3]; 3], e: Option<&[[f64; 3]; 3]>) -> Markup {
    html! {
        div.table-wrap tabindex="0" role="region" aria-label=(name) { table #{"triad-" (name)} .numbers {
            caption { (caption) }
            thead { tr {
                th scope="col" { "row" }
                @for axis in AXES { th scope="col" { (name) "·" (axis) } th scope="col" { "u" } }
            } }
            tbody {
                @for (r, axis) in AXES.iter().enumerate() {
                    (vector(&format!("{name}_{axis}"), &m[r], e.map(|e| &e[r])))
                }
            }
        } }
    }
}

/// The page of triad `d`.
pub async fn page(state: &AppState, viewer: &Viewer, d: TriadDoc) -> Result<Html, UiError> {
    let id = d.id.to_string();
    let (review_state, signatures) = record(state, &id).await?;
    let known = d.method == "known_orientations";
    let content = html! {
        p.muted {
            a href="/ui/sensors" { "Fleet" } " / "
            a href={"/ui/sensors/" (d.sensor_id)} { (d.sensor_id) } " / triad calibration"
        }
        h1 { "Triad calibration of " (d.sensor_id) " " (review::state_badge(review_state)) }
        @if let Some(n) = review::notice(review_state, &signatures) {
            p.notice.error role="status" { (n) }
        }
        p.lead { "Performed " (when(&d.performed_at)) }
        dl.facts {
            div { dt { "Calibration id" } dd { code { (d.id) } } }
            div { dt { "Station" } dd { (d.station_id.as_deref().unwrap_or("—")) } }
            div { dt { "Received" } dd { (when(&d.received_at)) } }
            div { dt { "Model" } dd { "u = b + S g; compensation g = T (u − b), T = S⁻¹" } }
            div { dt { "Method" } dd {
                @if known { "known orientations: each axis identified and fused by the single-axis method" }
                @else { "unknown orientations: b and T from the gravity magnitude (Levenberg–Marquardt)" }
            } }
            div { dt { "Unit" } dd { (d.unit) " (b); " (d.unit) " per g (S)" } }
        }
        p.no-print {
            "Download: "
            @for (k, (format, label)) in EXPORTS.iter().enumerate() {
                @if k > 0 { " · " }
                a href={"/ui/calibrations/" (d.id) "/export/" (format)} { (label) }
            }
            " · " a href={"/ui/calibrations/" (d.id) "/submission"} { "Submission as stored" }
        }
        h2 { "Bias and matrices" }
        div.table-wrap tabindex="0" role="region" aria-label="b" { table #triad-b .numbers {
            caption { "Bias b, " (d.unit) ", with standard errors u" }
            thead { tr { th scope="col" { "vector" } @for axis in AXES { th scope="col" { "b·" (axis) } th scope="col" { "u" } } } }
            tbody { (vector("b", &d.b, d.b_std_errors.as_ref())) }
        } }
        (matrix("Scale and misalignment S (rows by axis), with standard errors u", "S", &d.s, d.s_std_errors.as_ref()))
        (matrix("T = S⁻¹, with standard errors u", "T", &d.t, d.t_std_errors.as_ref()))
        dl.facts {
            div { dt { "Scale factors (row norms of S)" } dd {
                @for (k, axis) in AXES.iter().enumerate() { (axis) " " (num(d.scale_factors[k])) " " }
            } }
            div { dt { "Non-orthogonality (xy, yz, zx)" } dd {
                @for (k, pair) in ["xy", "yz", "zx"].iter().enumerate() {
                    (pair) " " (num(d.non_orthogonality_deg[k])) "° "
                }
            } }
            @if let Some(f) = &d.fit {
                div { dt { "Fit" } dd {
                    "RMS residual " (num(f.rms_g)) " g; " (f.evaluations) " evaluations (" (f.stop)
                    "); spread of the directions " (num(f.spread))
                } }
            }
        }
        h2 { "Residuals" }
        div.table-wrap tabindex="0" role="region" aria-label="Residuals" { table #triad-residuals .numbers {
            caption {
                @if known { "Per position: ū − (b + S g), " (d.unit) ", per axis" }
                @else { "Per position: ‖T (ū − b)‖ − 1, g" }
            }
            thead { tr {
                th scope="col" { "position" }
                @if known { @for axis in AXES { th scope="col" { (axis) } } }
                @else { th scope="col" { "g" } }
            } }
            tbody {
                @for (p, r) in d.residuals.iter().enumerate() {
                    tr { th scope="row" { (p + 1) } @for x in r { td.num { (num(*x)) } } }
                }
            }
        } }
        (review::section(&id, review_state, &signatures, viewer))
    };
    Ok(Html::ok(layout(
        &format!("Triad calibration of {}", d.sensor_id),
        Some(viewer),
        content,
    )))
}

/// `GET /ui/calibrations/{id}/export/{format}`: a stored triad's firmware
/// file, as `GET /v1/calibrations/{id}/export?format=` answers it.
pub async fn export(
    State(state): State<AppState>,
    _viewer: Viewer,
    Path((raw, format)): Path<(String, String)>,
) -> Result<Response, UiError> {
    let id = path_id(&raw, "calibration")?;
    Ok(crate::http::triads::exported(&state, id, &format).await?)
}
