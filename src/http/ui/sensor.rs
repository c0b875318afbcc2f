//! `GET /ui/sensors/{sensor_id}`: one chart per coefficient (a triad's:
//! per measured element of `b`, `S` and `S2`) over
//! `performed_at`, with ±expanded-uncertainty error bars (±2 fused standard
//! errors for calibrations stored without a budget), the individuals-chart
//! control limits and the fitted drift line; the stability numbers; the list
//! of calibrations. `from` and `to` (dates or RFC 3339) narrow the window,
//! `after` pages the list. Bounded whatever the history's length: the charts,
//! their tables and the stability cover the window's latest
//! [`MAX_SERIES`](crate::http::stability::MAX_SERIES) calibrations (saying
//! so when the window holds more), the list 50 a page.

use accelcal_core::Term;
use accelcal_core::history::TermStability;
use axum::extract::{Path, RawQuery, State};
use maud::{Markup, html};
use uuid::Uuid;

use super::format::{Notation, date, instant, num, opt, unc};
use super::plot::{self, Chart, Point, Rule, Segment, Series, XAxis};
use super::viewer::Viewer;
use super::{Html, UiError, badge, live_layout};
use crate::domain::timestamp::Timestamp;
use crate::http::AppState;
use crate::http::page::Page;
use crate::http::problem::Problem;
use crate::http::stability::{Report, report_of, years};
use crate::store::{CalibrationSummary, HistoryQuery, TriadElement};

/// Calibrations listed per page.
const PAGE: usize = 50;

/// `from`/`to`: a date (`2026-01-31`: the whole day) or an RFC 3339 instant.
fn bound(name: &str, raw: Option<&str>, end_of_day: bool) -> Result<Option<Timestamp>, Problem> {
    let Some(raw) = raw.filter(|r| !r.is_empty()) else {
        return Ok(None);
    };
    let text = if raw.len() == 10 {
        format!(
            "{raw}T{}Z",
            if end_of_day {
                "23:59:59.999999"
            } else {
                "00:00:00"
            }
        )
    } else {
        raw.to_owned()
    };
    Timestamp::parse(&text).map(Some).map_err(|_| {
        Problem::bad_parameter(name, "must be a date (2026-01-31) or an RFC 3339 instant")
    })
}

struct Query {
    from: Option<Timestamp>,
    to: Option<Timestamp>,
    from_raw: String,
    to_raw: String,
    after: Option<Uuid>,
}

fn query(raw: Option<&str>) -> Result<Query, Problem> {
    let mut q = Query {
        from: None,
        to: None,
        from_raw: String::new(),
        to_raw: String::new(),
        after: None,
    };
    for (k, v) in form_urlencoded::parse(raw.unwrap_or_default().as_bytes()) {
        match k.as_ref() {
            "from" => {
                q.from = bound("from", Some(&v), false)?;
                q.from_raw = v.into_owned();
            }
            "to" => {
                q.to = bound("to", Some(&v), true)?;
                q.to_raw = v.into_owned();
            }
            "after" if !v.is_empty() => {
                q.after =
                    Some(Uuid::try_parse(&v).map_err(|_| {
                        Problem::bad_parameter("after", "must be a calibration id")
                    })?);
            }
            _ => {}
        }
    }
    Ok(q)
}

/// An error bar's half-length: the expanded uncertainty (`true`), or two
/// standard errors for a calibration stored without one (`false`).
type ErrorBar = (f64, bool);

/// One charted quantity over the series: a single-axis term, or a
/// triad's element (`b_x`, `S_yx`, `S2_z`).
struct Quantity<'a> {
    /// Its name.
    name: String,
    /// Per calibration of the series, oldest first: its value and error
    /// bar, when it has this quantity.
    values: Vec<Option<(f64, Option<ErrorBar>)>>,
    /// Its stability over the series.
    stability: Option<&'a TermStability>,
}

/// An error bar: `U`, else two standard errors.
fn bar(expanded: Option<f64>, std_error: Option<f64>) -> Option<ErrorBar> {
    expanded
        .map(|u| (u, true))
        .or_else(|| std_error.map(|se| (2.0 * se, false)))
}

/// Every quantity of the window: a single-axis sensor's terms in model
/// order, a triad's measured elements of `b`, `S` and `S2` in the order of
/// first appearance.
fn quantities(r: &Report) -> Vec<Quantity<'_>> {
    let series = &r.series;
    let mut names: Vec<String> = Vec::new();
    let mut add = |name: String| {
        if !names.contains(&name) {
            names.push(name);
        }
    };
    let mut terms: Vec<Term> = series
        .iter()
        .flat_map(|c| c.coefficients.iter().map(|(t, _)| t))
        .collect();
    terms.sort();
    terms.dedup();
    for t in &terms {
        add(t.name().to_owned());
    }
    let measured: Vec<Vec<TriadElement>> = series
        .iter()
        .map(|c| {
            c.triad
                .as_ref()
                .map(|t| t.elements().into_iter().filter(|e| e.measured).collect())
                .unwrap_or_default()
        })
        .collect();
    for e in measured.iter().flatten() {
        add(e.name.clone());
    }
    names
        .into_iter()
        .map(|name| {
            let term = terms.iter().find(|t| t.name() == name).copied();
            let values = series
                .iter()
                .zip(&measured)
                .map(|(c, elements)| match term {
                    Some(t) => c.coefficients.get(t).map(|v| {
                        let u = c.expanded.as_ref().and_then(|e| e.get(t).copied());
                        (*v, bar(u, c.std_errors.get(t).copied()))
                    }),
                    None => elements
                        .iter()
                        .find(|e| e.name == name)
                        .map(|e| (e.value, bar(e.expanded, e.std_error))),
                })
                .collect();
            let stability = match term {
                Some(t) => r.stability.terms.get(t),
                None => r.stability.elements.as_ref().and_then(|e| e.get(&name)),
            };
            Quantity {
                name,
                values,
                stability,
            }
        })
        .collect()
}

/// The chart of one quantity.
fn chart(r: &Report, q: &Quantity<'_>, unit: &str) -> Chart {
    let s = q.stability;
    let name = &q.name;
    let flagged = |id: &Uuid| s.is_some_and(|s| s.control.out_of_control.contains(&id.to_string()));
    let points: Vec<Point> = r
        .series
        .iter()
        .zip(&q.values)
        .filter_map(|(c, v)| {
            let (v, err) = (*v)?;
            Some(Point {
                x: c.performed_at.unix_micros() as f64 / 1e6,
                y: v,
                err: err.map(|(e, _)| e),
                data: vec![("calibration-id", c.id.to_string())],
                label: format!(
                    "{}: {name} = {} ± {} {unit}",
                    date(&c.performed_at),
                    num(v),
                    err.map_or("—".into(), |(e, _)| unc(e))
                ),
                flagged: flagged(&c.id),
            })
        })
        .collect();
    let mut rules = Vec::new();
    let mut segments = Vec::new();
    if let Some(s) = s {
        rules.push(Rule {
            y: s.control.centre,
            label: "centre (mean)".into(),
            class: "centre",
        });
        if let (Some(lo), Some(hi)) = (s.control.lower, s.control.upper) {
            rules.push(Rule {
                y: lo,
                label: "control limits: mean ∓ 2.66 × mean moving range".into(),
                class: "limit",
            });
            rules.push(Rule {
                y: hi,
                label: "upper control limit: mean + 2.66 × mean moving range".into(),
                class: "limit",
            });
        }
        if let (Some(b), Some(first), Some(last)) =
            (s.drift_per_year, r.series.first(), r.series.last())
        {
            let t_mean =
                r.series.iter().map(|c| years(c.performed_at)).sum::<f64>() / r.series.len() as f64;
            let at = |c: &CalibrationSummary| {
                (
                    c.performed_at.unix_micros() as f64 / 1e6,
                    s.mean + b * (years(c.performed_at) - t_mean),
                )
            };
            segments.push(Segment {
                from: at(first),
                to: at(last),
                label: format!("drift {} {unit}/year", unc(b)),
                class: "drift",
            });
        }
    }
    Chart {
        id: format!("chart-{name}"),
        title: format!(
            "{name} of {} over time, with error bars",
            r.sensor.sensor_id
        ),
        y_label: format!("{name} ({unit})"),
        x: XAxis::Time,
        series: vec![Series {
            name: name.clone(),
            points,
        }],
        rules,
        segments,
    }
}

/// The table beside a quantity's chart: the same points.
fn chart_table(r: &Report, q: &Quantity<'_>) -> Markup {
    let s = q.stability;
    let name = &q.name;
    let values = Notation::of(q.values.iter().flatten().map(|(v, _)| *v));
    let bars = Notation::of(
        q.values
            .iter()
            .flatten()
            .filter_map(|(_, e)| e.map(|(e, _)| e)),
    );
    html! {
        div.table-wrap tabindex="0" role="region" aria-label={(name) " per calibration"} {
            table data-term=(name) .cards {
                caption { (name) " per calibration, newest first (error bar: expanded uncertainty U, or 2σ)" }
                thead { tr {
                    th scope="col" { "Performed" }
                    th scope="col" .num { (name) }
                    th scope="col" .num { "±" }
                    th scope="col" { "" }
                } }
                tbody {
                    // Newest first: the rows a scrolled-off box shows are the latest.
                    @for (c, value) in r.series.iter().zip(&q.values).rev() {
                        @if let Some((v, err)) = value {
                            tr data-calibration-id=(c.id) {
                                td data-label="Performed" { a href={"/ui/calibrations/" (c.id)} { (date(&c.performed_at)) } }
                                td.num data-label=(name) data-value=(v) { (values.num(*v)) }
                                td.num data-label="±" { @match err {
                                    Some((e, true)) => { (bars.unc(*e)) " (U)" },
                                    Some((e, false)) => { (bars.unc(*e)) " (2σ)" },
                                    None => "—",
                                } }
                                td data-label="Control" { @if s.is_some_and(|s| s.control.out_of_control.contains(&c.id.to_string())) {
                                    span.badge.fail title="outside the control limits" { "out" }
                                } }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// One notation per column of the stability table, each decided by every
/// row's number in it.
struct StabilityColumns {
    mean: Notation,
    std: Notation,
    min: Notation,
    max: Notation,
    drift: Notation,
    se: Notation,
    limits: Notation,
    change: Notation,
    change_u: Notation,
}

impl StabilityColumns {
    fn of<'a>(rows: impl Iterator<Item = &'a TermStability> + Clone) -> Self {
        let col = |f: fn(&TermStability) -> Option<f64>| Notation::of(rows.clone().filter_map(f));
        StabilityColumns {
            mean: col(|s| Some(s.mean)),
            std: col(|s| s.std),
            min: col(|s| Some(s.min)),
            max: col(|s| Some(s.max)),
            drift: col(|s| s.drift_per_year),
            se: col(|s| s.drift_std_error),
            limits: Notation::of(
                rows.clone()
                    .flat_map(|s| [s.control.lower, s.control.upper])
                    .flatten(),
            ),
            change: col(|s| s.latest_change),
            change_u: col(|s| s.latest_change_expanded),
        }
    }
}

/// An optional number in a column's notation.
fn opt_in(v: Option<f64>, n: Notation, f: fn(Notation, f64) -> String) -> String {
    v.map_or("—".into(), |v| f(n, v))
}

fn stability_table(r: &Report) -> Markup {
    // A triad's: element by element (`b_x`, `S_xy`, `T_zz`).
    let triad = r.stability.elements.is_some();
    let rows: Vec<(String, &TermStability)> = match &r.stability.elements {
        Some(e) => e.iter().map(|(n, s)| (n.clone(), s)).collect(),
        None => r
            .stability
            .terms
            .iter()
            .map(|(t, s)| (t.name().to_owned(), s))
            .collect(),
    };
    let cols = StabilityColumns::of(rows.iter().map(|(_, s)| *s));
    html! {
        @if rows.is_empty() {
            p.muted { "No coefficient is present in every calibration of the window." }
        } @else {
            div.table-wrap tabindex="0" role="region" aria-label="Stability" {
                table #stability .cards {
                    caption {
                        (r.stability.calibrations) " calibrations; drift by least squares over years of 365.25 days; "
                        "latest change judged with k = " (r.stability.coverage_factor)
                    }
                    thead { tr {
                        th scope="col" { @if triad { "Element" } @else { "Term" } }
                        th scope="col" .num { "Mean" }
                        th scope="col" .num { "Std" }
                        th scope="col" .num { "Min" }
                        th scope="col" .num { "Max" }
                        th scope="col" .num { "Drift / year" }
                        th scope="col" .num { "SE" }
                        th scope="col" .num { "t" }
                        th scope="col" .num { "Control limits" }
                        th scope="col" .num { "Latest change" }
                        th scope="col" .num { "U of change" }
                        th scope="col" { "Significant" }
                    } }
                    tbody {
                        @for (t, s) in &rows {
                            tr data-term=(t) {
                                th scope="row" { (t) }
                                td.num data-label="Mean" { (cols.mean.num(s.mean)) }
                                td.num data-label="Std" { (opt_in(s.std, cols.std, Notation::unc)) }
                                td.num data-label="Min" { (cols.min.num(s.min)) }
                                td.num data-label="Max" { (cols.max.num(s.max)) }
                                td.num data-label="Drift / year" { (opt_in(s.drift_per_year, cols.drift, Notation::unc)) }
                                td.num data-label="SE" { (opt_in(s.drift_std_error, cols.se, Notation::unc)) }
                                td.num data-label="t" { (opt(s.drift_t, |v| format!("{v:.2}"))) }
                                td.num data-label="Control limits" { @match (s.control.lower, s.control.upper) {
                                    (Some(lo), Some(hi)) => { (cols.limits.num(lo)) " … " (cols.limits.num(hi)) },
                                    _ => "—",
                                } }
                                td.num data-label="Latest change" { (opt_in(s.latest_change, cols.change, Notation::unc)) }
                                td.num data-label="U of change" { (opt_in(s.latest_change_expanded, cols.change_u, Notation::unc)) }
                                td data-label="Significant" { @match s.latest_change_significant {
                                    Some(true) => (badge("fail", "yes")),
                                    Some(false) => (badge("pass", "no")),
                                    None => span.muted { "—" },
                                } }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// `GET /ui/sensors/{sensor_id}`.
pub async fn page(
    State(state): State<AppState>,
    viewer: Viewer,
    Path(sensor_id): Path<String>,
    RawQuery(raw): RawQuery,
) -> Result<Html, UiError> {
    let q = query(raw.as_deref())?;
    let report = report_of(&state, &sensor_id, q.from, q.to).await?;
    if let Some(id) = q.after {
        let known = state.store.calibration_summary(id).await?;
        if known.is_none_or(|c| c.sensor_id != sensor_id) {
            return Err(Problem::not_found(
                "this sensor has no such calibration to continue after",
            )
            .into());
        }
    }
    let history = state
        .store
        .history(
            sensor_id.clone(),
            HistoryQuery {
                from: q.from,
                to: q.to,
                before: q.after,
                limit: PAGE + 1,
            },
        )
        .await?;
    let history = Page::from_overfetch(history, PAGE, |c| c.id.to_string());
    let s = &report.sensor;
    let unit = s.latest.unit.clone();
    let window = |after: Option<&str>| {
        let mut ser = form_urlencoded::Serializer::new(String::new());
        if !q.from_raw.is_empty() {
            ser.append_pair("from", &q.from_raw);
        }
        if !q.to_raw.is_empty() {
            ser.append_pair("to", &q.to_raw);
        }
        if let Some(a) = after {
            ser.append_pair("after", a);
        }
        let qs = ser.finish();
        if qs.is_empty() {
            format!("/ui/sensors/{sensor_id}")
        } else {
            format!("/ui/sensors/{sensor_id}?{qs}")
        }
    };
    let content = html! {
        p.muted { a href="/ui/sensors" { "Fleet" } " / sensor" }
        h1 { (s.sensor_id) " " (badge(s.status.as_str(), &s.status.as_str().replace('_', " "))) }
        dl.facts {
            div { dt { "Sensor type" } dd { (s.sensor_type.as_deref().unwrap_or("none")) } }
            div { dt { "Calibrations" } dd { (s.calibration_count) } }
            div { dt { "First performed" } dd { (instant(&s.first_performed_at)) } }
            div { dt { "Latest performed" } dd { a href={"/ui/calibrations/" (s.latest.id)} { (instant(&s.latest_performed_at)) } } }
            div { dt { "Latest verdict" } dd { @match s.latest_verdict { Some(v) => (badge(v.as_str(), v.as_str())), None => "—" } } }
            div { dt { "Due" } dd { @match &s.due_at { Some(d) => (date(d)), None => "—" } } }
        }
        form.filters method="get" action={"/ui/sensors/" (s.sensor_id)} {
            label for="from" { "From" input id="from" name="from" type="date" value=(q.from_raw); }
            label for="to" { "To" input id="to" name="to" type="date" value=(q.to_raw); }
            button type="submit" { "Show window" }
            @if q.from.is_some() || q.to.is_some() { a href={"/ui/sensors/" (s.sensor_id)} { "Whole history" } }
        }
        h2 { "Coefficients over time" }
        @if report.stability.omitted > 0 {
            p.notice #capped {
                "The charts and the stability cover the latest " (report.series.len())
                " of the window's " (report.series.len() + report.stability.omitted)
                " calibrations; choose a window (From, To) to see earlier ones. The list below has them all."
            }
        }
        @if report.stability.other_units > 0 {
            p.notice #other-units {
                "The charts and the stability are in " (report.stability.unit.as_deref().unwrap_or("?"))
                ", the latest calibration's unit; " (report.stability.other_units)
                " calibration(s) of the window in another unit are left out (the list below has them)."
            }
        }
        @if report.series.is_empty() {
            p.notice { "No calibration in this window." }
        } @else {
            div.charts {
                @for q in quantities(&report) {
                    section.chart-block aria-label={(q.name) " over time"} {
                        (plot::render(&chart(&report, &q, &unit)))
                        (chart_table(&report, &q))
                    }
                }
            }
        }
        h2 { "Stability" }
        (stability_table(&report))
        h2 #calibrations { "Calibrations" }
        div.table-wrap tabindex="0" role="region" aria-label="Calibrations" {
            table #history .cards {
                caption { "Newest performed first" }
                thead { tr {
                    th scope="col" { "Performed" }
                    th scope="col" { "Calibration" }
                    th scope="col" { "Station" }
                    th scope="col" .num { "Runs" }
                    th scope="col" { "Type" }
                    th scope="col" { "Verdict" }
                    th scope="col" { "Due" }
                    th scope="col" { "Certificate" }
                } }
                tbody {
                    @for c in &history.items {
                        tr data-calibration-id=(c.id) {
                            td data-label="Performed" { (instant(&c.performed_at)) }
                            td data-label="Calibration" { a href={"/ui/calibrations/" (c.id)} { code { (c.id.to_string().get(..13).unwrap_or_default()) "…" } } }
                            td data-label="Station" { (c.station_id.as_deref().unwrap_or("—")) }
                            td.num data-label="Runs" { (c.runs) }
                            td data-label="Type" { (c.sensor_type.as_deref().unwrap_or("—")) }
                            td data-label="Verdict" { @match c.verdict { Some(v) => (badge(v.as_str(), v.as_str())), None => "—" } }
                            td data-label="Due" { @match &c.due_at { Some(d) => (date(d)), None => "—" } }
                            td data-label="Certificate" { a href={"/ui/calibrations/" (c.id) "/certificate"} { "certificate" } }
                        }
                    }
                }
            }
        }
        nav.pages aria-label="Pages of calibrations" {
            @if q.after.is_some() { a href=(window(None)) { "Newest" } }
            @if let Some(next) = &history.next { a href=(window(Some(next))) rel="next" { "Older" } }
        }
    };
    Ok(Html::ok(live_layout(
        &s.sensor_id,
        &viewer,
        Some(&sensor_id),
        content,
    )))
}
