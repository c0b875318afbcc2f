//! `GET /ui/calibrations/{id}`: one calibration of any kind as a lab reads
//! it — written once: its state and review, what it supersedes, its facts,
//! links to the certificate, the DCC and the submission, and its kind's own
//! sections ([`super::kinds`]: a single axis's tables per run and fused,
//! residuals, budget; a triad's `b`, `S`, `T` and firmware files).
//! `GET /ui/calibrations/{id}/submission` downloads the stored body, byte
//! for byte; the certificate, DCC and export routes answer the documents.

use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use maud::html;

use super::stored::{load_stored, record, when};
use super::viewer::Viewer;
use super::{Html, UiError, layout, review};
use crate::http::problem::Problem;
use crate::http::{AppState, path_id};

/// `GET /ui/calibrations/{id}`: a calibration of any kind — its state,
/// what it supersedes, its facts, the downloads, its kind's sections, the
/// review and (to reviewers) its audit trail.
pub async fn page(
    State(state): State<AppState>,
    viewer: Viewer,
    Path(id): Path<String>,
) -> Result<Html, UiError> {
    let stored = load_stored(&state, &id).await?;
    let d = super::kinds::page(&stored);
    let (review_state, signatures) = record(&state, &id).await?;
    let trail = if viewer.principal.role >= crate::domain::auth::Role::Reviewer {
        let q = crate::store::AuditQuery {
            object: Some(crate::domain::audit::calibration(d.id)),
            limit: crate::domain::limits::MAX_PAGE,
            ..crate::store::AuditQuery::default()
        };
        Some(state.store.audit(q).await?)
    } else {
        None
    };
    let content = html! {
        p.muted {
            a href="/ui/sensors" { "Fleet" } " / "
            a href={"/ui/sensors/" (d.sensor_id)} { (d.sensor_id) } " / " (d.noun)
        }
        h1 { (d.title) " of " (d.sensor_id) " "
            @if let Some(v) = &d.verdict { (v) " " }
            (review::state_badge(review_state)) }
        @if let Some(n) = review::notice(review_state, &signatures) {
            p.notice.error role="status" { (n) }
        }
        @if let Some(s) = d.supersedes {
            p.notice role="note" {
                "This calibration supersedes "
                a href={"/ui/calibrations/" (s.calibration_id)} { code { (s.calibration_id) } }
                ": " (s.reason)
            }
        }
        p.lead { "Performed " (when(d.performed_at)) }
        dl.facts {
            div { dt { "Calibration id" } dd { code { (d.id) } } }
            div { dt { "Station" } dd { (d.station_id.unwrap_or("—")) } }
            div { dt { "Received" } dd { (when(d.received_at)) } }
            (d.facts)
        }
        p.no-print {
            @if let Some(x) = &d.downloads { (x) " · " }
            @if d.certified {
                a href={"/ui/calibrations/" (d.id) "/certificate"} { "Certificate" } " · "
                a #dcc-link href={"/ui/calibrations/" (d.id) "/certificate.xml"} type="application/xml" { "Digital Calibration Certificate (XML)" } " · "
            }
            a href={"/ui/calibrations/" (d.id) "/submission"} { "Submission as stored" }
        }
        (d.sections)
        (review::section(&d.id.to_string(), review_state, &signatures, &viewer))
        @if let Some(entries) = &trail { (review::trail(entries)) }
    };
    Ok(Html::ok(layout(
        &format!("{} of {}", d.title, d.sensor_id),
        Some(&viewer),
        content,
    )))
}

/// `GET /ui/calibrations/{id}/submission`: the stored body, as a download.
pub async fn submission(
    State(state): State<AppState>,
    _viewer: Viewer,
    Path(raw): Path<String>,
) -> Result<Response, UiError> {
    let id = path_id(&raw, "calibration")?;
    let s = state
        .store
        .submission(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    let ext = if s.content_type.starts_with("text/csv") {
        "csv"
    } else {
        "json"
    };
    let mut res = s.body.into_response();
    let h = res.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_str(&s.content_type)
            .unwrap_or(HeaderValue::from_static("application/octet-stream")),
    );
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{id}.{ext}\"")) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(res)
}

/// `GET /ui/calibrations/{id}/certificate`.
pub async fn certificate(
    State(state): State<AppState>,
    _viewer: Viewer,
    headers: HeaderMap,
    Path(id): Path<String>,
    RawQuery(query): RawQuery,
) -> Result<Response, UiError> {
    certificate_of(&state, &headers, &id, query, false).await
}

/// `GET /ui/calibrations/{id}/certificate.xml`: the Digital Calibration
/// Certificate, for the page's link (a browser cannot choose `Accept`).
pub async fn dcc(
    State(state): State<AppState>,
    _viewer: Viewer,
    headers: HeaderMap,
    Path(id): Path<String>,
    RawQuery(query): RawQuery,
) -> Result<Response, UiError> {
    certificate_of(&state, &headers, &id, query, true).await
}

/// Calibration `id`'s certificate at the `?revision=` of `query`, as
/// issued: the DCC when `xml`, the printable HTML otherwise.
async fn certificate_of(
    state: &AppState,
    headers: &HeaderMap,
    id: &str,
    query: Option<String>,
    xml: bool,
) -> Result<Response, UiError> {
    let revision = super::issue::revision(query.as_deref())?;
    Ok(super::issue::respond(state, headers, id, revision, xml).await?)
}

/// `GET /ui/calibrations/{id}/export/{format}`: a stored triad's firmware
/// file, as `GET /v1/calibrations/{id}/export?format=` answers it.
pub async fn export(
    State(state): State<AppState>,
    _viewer: Viewer,
    Path((raw, format)): Path<(String, String)>,
) -> Result<Response, UiError> {
    let id = path_id(&raw, "calibration")?;
    Ok(crate::http::firmware::exported(&state, id, &format).await?)
}
