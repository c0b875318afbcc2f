//! A temperature model on its calibration page (issue 45): its range and
//! reference, every coefficient at `T_ref`, each set point's fused
//! coefficients, and every polynomial `c(T) = Σ a_d (T − T_ref)^d` with
//! the standard uncertainties of its `a_d`, its degree and how it was
//! chosen, `χ²/ν` and the covariance's inflation; the decision's and the
//! set points' tables are the certificate's too.

use accelcal_core::thermal::Polynomial;
use maud::{Markup, html};

use accelcal_core::decision::Rule;

use crate::domain::thermal::decision::{ThermalDecision, ThermalTermDecision};
use crate::http::ui::badge;
use crate::http::ui::document::Page;
use crate::http::ui::format::{Notation, num, unc};
use crate::http::ui::thermal_result::ThermalDoc;

/// The facts' line naming the stored calibrations a model was fitted
/// from, each linked by the last eight digits of its id (nothing for runs
/// sent whole).
pub fn fitted_from(ids: &[uuid::Uuid]) -> Markup {
    html! {
        @if !ids.is_empty() {
            div { dt { "Fitted from" } dd {
                @for (i, c) in ids.iter().enumerate() {
                    @if i > 0 { ", " }
                    // A UUIDv7 begins with its time: ids stored within a
                    // minute share their first eight digits, not their last.
                    @let id = c.to_string();
                    a href={"/ui/calibrations/" (id)} title=(id) { code { "…" (id.get(id.len() - 8..).unwrap_or_default()) } }
                }
                " (stored calibrations, each at its own temperature)"
            } }
        }
    }
}

/// A temperature to 0.01 K, as the page and certificate print it.
pub fn celsius(t: f64) -> String {
    // Within half a hundredth of zero, zero (not `-0.00`).
    let t = if t.abs() < 0.005 { 0.0 } else { t };
    format!("{t:.2}")
}

/// `d` as its page shows it.
pub fn page(d: &ThermalDoc) -> Page<'_> {
    let m = &d.thermal;
    Page {
        id: d.id,
        sensor_id: &d.sensor_id,
        title: "Temperature model",
        noun: "temperature model",
        verdict: Some(
            html! { @if let Some(dec) = &d.decision { (badge(dec.verdict.as_str(), dec.verdict.as_str())) } },
        ),
        supersedes: d.supersedes.as_ref(),
        performed_at: &d.performed_at,
        station_id: d.station_id.as_deref(),
        received_at: &d.received_at,
        facts: html! {
            div { dt { "Valid from" } dd { (celsius(d.range_c[0])) " to " (celsius(d.range_c[1])) " °C (the set points' span)" } }
            div { dt { "Reference T_ref" } dd { (celsius(d.reference_c)) " °C" } }
            div { dt { "Set points" } dd { (m.set_points.len()) " (runs within " (m.tolerance_k) " K), " (d.runs) " runs" } }
            div { dt { "Degrees" } dd { (m.selection) } }
            @if let Some(t) = &d.sensor_type { div { dt { "Sensor type" } dd { (t) } } }
            (fitted_from(&d.from_calibrations))
            @if let Some(u) = m.thermometer_std_c { div { dt { "Thermometer" } dd { "u_T = " (u) " K, in every coefficient read at a temperature" } } }
        },
        downloads: None,
        certified: true,
        sections: html! {
            @if let Some(dec) = &d.decision {
                h2 { "Decision" }
                (terms_table(dec))
            }
            h2 { "Coefficients at T_ref" }
            div.table-wrap tabindex="0" role="region" aria-label="Coefficients at T_ref" { table #thermal-at-reference .numbers {
                caption { "c(T_ref) = a_0, in " (d.unit) " (per g for the scale terms), with standard uncertainty u (the thermometer's term included, when one was named)" }
                thead { tr { th scope="col" { "term" } th scope="col" { "c(T_ref)" } th scope="col" { "u" } } }
                tbody {
                    @for (t, c) in d.kind.coefficients.iter() {
                        tr { th scope="row" { (t.to_string()) } td.num { (num(*c)) }
                            td.num { (d.kind.std_errors.get(t).map_or("—".into(), |u| unc(*u))) } }
                    }
                }
            } }
            h2 { "Polynomials" }
            (polynomials_table("term", "c(T)", m.coefficients.iter().map(|(t, p)| (t.to_string(), p))))
            h2 { "Set points" }
            (set_points_table(d))
        },
    }
}

/// The polynomials' table: each `(name, polynomial)`'s degree, its `a_d`
/// with their standard uncertainties, `χ²/ν` and the inflation; `column`
/// names the rows (`term`, `element`), `what` the function (`c(T)`).
pub fn polynomials_table<'a>(
    column: &str,
    what: &str,
    rows: impl Iterator<Item = (String, &'a Polynomial)>,
) -> Markup {
    html! {
        div.table-wrap tabindex="0" role="region" aria-label="Polynomials" { table #thermal-polynomials .numbers {
            caption { (what) " = Σ a_d (T − T_ref)^d, a_d per K^d, with standard uncertainties u(a_d)" }
            thead { tr {
                th scope="col" { (column) } th scope="col" { "degree" }
                @for d in 0..=3 { th scope="col" { "a_" (d) } th scope="col" { "u" } }
                th scope="col" { "χ²/ν" } th scope="col" { "inflation" }
            } }
            tbody {
                @for (name, p) in rows {
                    tr {
                        th scope="row" { (name) }
                        td.num { (p.degree) }
                        @for d in 0..=3 {
                            td.num { (p.coefficients.get(d).map_or("—".into(), |a| num(*a))) }
                            td.num { (p.std_uncertainties.get(d).map_or("—".into(), |u| unc(*u))) }
                        }
                        td.num { @if p.dof > 0 { (num(p.chi2 / p.dof as f64)) } @else { "—" } }
                        td.num { (num(p.inflation)) }
                    }
                }
            }
        } }
    }
}

/// The decision's table of `rows` (each limited coefficient's or
/// element's worst judgement, with where) under `rule`; `column` heads
/// their names (`term`, `element`).
pub fn decision_table<'a>(
    rule: Rule,
    column: &str,
    rows: impl Iterator<Item = (String, &'a ThermalTermDecision)>,
) -> Markup {
    html! {
        div.table-wrap tabindex="0" role="region" aria-label="Decision" { table #thermal-decision .numbers {
            caption { "Each limited " (if column == "term" { "coefficient" } else { column }) " at every set point and across the range ("
                (rule_name(rule)) " rule): its worst" }
            thead { tr {
                th scope="col" { (column) } th scope="col" { "verdict" } th scope="col" { "at, °C" }
                th scope="col" { "value" } th scope="col" { "U" } th scope="col" { "k" }
                th scope="col" { "min" } th scope="col" { "max" }
            } }
            tbody {
                @for (t, j) in rows {
                    tr {
                        th scope="row" { (t) }
                        td { (badge(j.worst.verdict.as_str(), j.worst.verdict.as_str())) }
                        td.num { (celsius(j.worst.temperature_c)) }
                        td.num { (num(j.worst.value)) }
                        td.num { (unc(j.worst.expanded)) }
                        td.num { (num(j.worst.coverage_factor)) }
                        td.num { (j.min.map_or("—".into(), num)) }
                        td.num { (j.max.map_or("—".into(), num)) }
                    }
                }
            }
        } }
    }
}

/// A decision rule's wire name.
pub fn rule_name(rule: Rule) -> &'static str {
    match rule {
        Rule::Simple => "simple",
        Rule::Guarded => "guarded",
    }
}

/// The single axis's decision's table ([`decision_table`]).
pub fn terms_table(dec: &ThermalDecision) -> Markup {
    decision_table(
        dec.rule,
        "term",
        dec.terms.iter().map(|(t, j)| (t.to_string(), j)),
    )
}

/// The set points' table: each set point's fused coefficients with their
/// standard errors.
pub fn set_points_table(d: &ThermalDoc) -> Markup {
    let m = &d.thermal;
    let terms: Vec<String> = m.coefficients.iter().map(|(t, _)| t.to_string()).collect();
    html! {
        div.table-wrap tabindex="0" role="region" aria-label="Set points" { table #thermal-set-points .numbers {
            caption { "Each set point identified and fused: its coefficients with standard errors" }
            thead { tr {
                th scope="col" { "T, °C" } th scope="col" { "runs" }
                @for t in &terms { th scope="col" { (t) } th scope="col" { "u" } }
            } }
            @let notation: Vec<Notation> = terms.iter().map(|t| Notation::of(
                m.set_points.iter().filter_map(|s| s.coefficients.iter().find(|(x, _)| x.to_string() == *t).map(|(_, v)| *v))
            )).collect();
            tbody {
                @for s in &m.set_points {
                    tr {
                        th scope="row" { (celsius(s.temperature_c)) }
                        td.num { (s.runs.len()) }
                        @for (k, t) in terms.iter().enumerate() {
                            @let value = s.coefficients.iter().find(|(x, _)| x.to_string() == *t).map(|(_, v)| *v);
                            @let error = s.std_errors.iter().find(|(x, _)| x.to_string() == *t).map(|(_, v)| *v);
                            td.num { (value.map_or("—".into(), |v| notation[k].num(v))) }
                            td.num { (error.map_or("—".into(), unc)) }
                        }
                    }
                }
            }
        } }
    }
}
