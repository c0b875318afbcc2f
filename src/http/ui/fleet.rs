//! `GET /ui/sensors`: every sensor with its type, calibration count, latest
//! date and fused coefficients, verdict, due date and status; filtered by
//! status, searched by id, paginated like `GET /v1/sensors`.

use axum::extract::{RawQuery, State};
use maud::{Markup, html};

use super::format::{Notation, date};
use super::viewer::Viewer;
use super::{Html, UiError, badge, live_layout};
use crate::domain::status::Status;
use crate::http::AppState;
use crate::http::lookup::SensorListQuery;
use crate::http::page::Page;
use crate::http::problem::Problem;
use crate::store::SensorSummary;

/// The query with empty fields dropped (an empty select or search box means
/// "any"), read exactly as the API reads it.
fn query(raw: Option<&str>) -> Result<(SensorListQuery, Vec<(String, String)>), Problem> {
    let pairs: Vec<(String, String)> = form_urlencoded::parse(raw.unwrap_or_default().as_bytes())
        .filter(|(_, v)| !v.is_empty())
        .map(|(k, v)| (k.into_owned(), v.into_owned()))
        .collect();
    let cleaned = form_urlencoded::Serializer::new(String::new())
        .extend_pairs(&pairs)
        .finish();
    let q = serde_urlencoded::from_str::<SensorListQuery>(&cleaned)
        .map_err(|e| Problem::bad_request(format!("the filter is malformed: {e}")))?;
    Ok((q, pairs))
}

fn with(pairs: &[(String, String)], key: &str, value: Option<&str>) -> String {
    let mut s = form_urlencoded::Serializer::new(String::new());
    for (k, v) in pairs.iter().filter(|(k, _)| k != key && k != "after") {
        s.append_pair(k, v);
    }
    if let Some(v) = value {
        s.append_pair(key, v);
    }
    let q = s.finish();
    if q.is_empty() {
        "/ui/sensors".to_owned()
    } else {
        format!("/ui/sensors?{q}")
    }
}

/// The latest fused coefficients, one line, in the column's notation `n`.
pub fn coefficients(s: &SensorSummary, n: Notation) -> Markup {
    html! {
        span.coef {
            @for (term, v) in s.latest.coefficients.iter() {
                span { (term.name()) " " (n.num(*v)) } " "
            }
        }
    }
}

/// The one notation of the fleet's coefficient column: every coefficient
/// of every sensor listed.
pub fn coefficient_notation<'a>(sensors: impl Iterator<Item = &'a SensorSummary>) -> Notation {
    Notation::of(sensors.flat_map(|s| s.latest.coefficients.iter().map(|(_, v)| *v)))
}

/// `GET /ui/sensors`.
pub async fn page(
    State(state): State<AppState>,
    viewer: Viewer,
    RawQuery(raw): RawQuery,
) -> Result<Html, UiError> {
    let (q, pairs) = query(raw.as_deref())?;
    let (store_query, limit) = q.store_query()?;
    let status = store_query.status;
    let search = store_query.search.clone();
    let first_page = store_query.after.is_none();
    let items = state.store.sensors(store_query).await?;
    let page = Page::from_overfetch(items, limit, |s| s.sensor_id.clone());
    let filtered = status.is_some() || search.is_some();
    let content = html! {
        h1 { "Fleet" }
        p.lead { "Every calibrated sensor: its latest fused coefficients, verdict and when it is due." }
        form.filters method="get" action="/ui/sensors" role="search" {
            label for="status" {
                "Status"
                select id="status" name="status" {
                    option value="" selected[status.is_none()] { "any" }
                    @for s in Status::ALL {
                        option value=(s.as_str()) selected[status == Some(s)] { (s.as_str().replace('_', " ")) }
                    }
                }
            }
            label for="search" {
                "Sensor id contains"
                input id="search" name="search" type="search" value=[search.as_deref()]
                    maxlength="64" pattern="[A-Za-z0-9._:\\-]{1,64}" placeholder="ACC-";
            }
            button type="submit" { "Filter" }
            @if filtered {
                a href="/ui/sensors" { "Clear" }
            }
        }
        @if page.items.is_empty() {
            p.notice { @if filtered { "No sensor matches this filter." } @else { "No sensor has been calibrated yet." } }
        } @else {
            @let notation = coefficient_notation(page.items.iter());
            div.table-wrap tabindex="0" role="region" aria-label="Sensors" {
                table #fleet .cards {
                    caption { "Sensors in id order" @if !first_page { " (continued)" } }
                    thead {
                        tr {
                            th scope="col" { "Sensor" }
                            th scope="col" { "Type" }
                            th scope="col" .num { "Calibrations" }
                            th scope="col" { "Latest" }
                            th scope="col" { "Latest fused coefficients" }
                            th scope="col" { "Verdict" }
                            th scope="col" { "Due" }
                            th scope="col" { "Status" }
                        }
                    }
                    tbody {
                        @for s in &page.items {
                            tr data-sensor-id=(s.sensor_id) {
                                th scope="row" { a href={"/ui/sensors/" (s.sensor_id)} { (s.sensor_id) } }
                                td data-label="Type" { (s.sensor_type.as_deref().unwrap_or("—")) }
                                td.num data-label="Calibrations" { (s.calibration_count) }
                                td.date data-label="Latest" { a href={"/ui/calibrations/" (s.latest.id)} { (date(&s.latest_performed_at)) } }
                                td data-label="Coefficients" { (coefficients(s, notation)) " " span.muted { (s.latest.unit) } }
                                td data-label="Verdict" { @match s.latest_verdict {
                                    Some(v) => (badge(v.as_str(), v.as_str())),
                                    None => span.muted { "—" },
                                } }
                                td.date data-label="Due" { @match &s.due_at { Some(d) => (date(d)), None => span.muted { "—" } } }
                                td data-label="Status" { (badge(s.status.as_str(), &s.status.as_str().replace('_', " "))) }
                            }
                        }
                    }
                }
            }
        }
        nav.pages aria-label="Pages" {
            @if !first_page {
                a href=(with(&pairs, "after", None)) { "First page" }
            }
            @if let Some(next) = &page.next {
                a href=(with(&pairs, "after", Some(next))) rel="next" { "Next page" }
            }
        }
    };
    Ok(Html::ok(live_layout("Fleet", &viewer, None, content)))
}
