//! A triad's temperature model on its page and in its documents (issue
//! 45): its range and reference, `b` and `S` at `T_ref`, every element's
//! polynomial and each set point's fused `b`; the firmware files of the
//! model (PX4's and ArduPilot's thermal parameters, a C header, the JSON)
//! to download; its certificate and DCC list every polynomial's `a_d` as
//! a single axis's model does ([`super::polynomials`]), `b`'s in the
//! outputs' unit per K^d and `S`'s per g per K^d, at the sensor type's
//! coverage, with the type's decision element by element, the standards
//! and the thermometer's term.

use maud::{Markup, html};

use super::page::{celsius, decision_table, fitted_from, polynomials_table, rule_name};
use super::polynomials;
use crate::domain::thermal::decision::TriadThermalDecision;
use crate::domain::triad::{FIXED_BY_CONVENTION, GRAVITY_MAGNITUDE};
use crate::http::ui::badge;
use crate::http::ui::certificate::{Context, PAPER, standards};
use crate::http::ui::document::{Admin, Column, DccText, Document, Page, Printed, Quantity};
use crate::http::ui::format::{Notation, num, unc};
use crate::http::ui::kinds::triad::meaning;
use crate::http::ui::stored::when;
use crate::http::ui::thermal_result::ThermalTriadDoc;
use crate::store::AXES;

/// The firmware files offered, with their labels.
const EXPORTS: [(&str, &str); 4] = [
    ("px4", "PX4 thermal parameters"),
    ("ardupilot", "ArduPilot thermal parameters"),
    ("c", "C header"),
    ("json", "JSON"),
];

/// Every element's `a_d`: `b` first, then `S` by rows, at the model's
/// coverage.
pub fn quantities(d: &ThermalTriadDoc) -> Vec<Quantity> {
    let each = d.thermal.polynomials().map(|(name, p)| {
        let (matrix, m, k) = element(&name);
        let unit = match matrix {
            "b" => d.unit.clone(),
            _ => format!("{}/g", d.unit),
        };
        (name, meaning(matrix, m, k), unit, p)
    });
    let mut out = polynomials(each, d.coverage);
    if d.thermal.method == GRAVITY_MAGNITUDE {
        for q in &mut out {
            let (matrix, m, k) = element(&q.name);
            if matrix == "S" && FIXED_BY_CONVENTION.contains(&(m, k)) {
                q.fixed = Some("by the frame convention");
                (q.std_error, q.expanded, q.covered) = (None, None, None);
            }
        }
    }
    out
}

/// `("b", m, m)` of `b_x`, `("S", m, k)` of `S_xy`.
fn element(name: &str) -> (&'static str, usize, usize) {
    let axis = |c: char| AXES.iter().position(|a| a.starts_with(c)).unwrap_or(0);
    let mut chars = name.chars().skip(2);
    let m = chars.next().map_or(0, axis);
    match name.as_bytes().first() {
        Some(b'b') => ("b", m, m),
        _ => ("S", m, chars.next().map_or(0, axis)),
    }
}

/// The set points' fused `b` with standard errors (`S` is in the
/// calibration's JSON: twelve columns do not fit a page).
fn set_points_table(d: &ThermalTriadDoc) -> Markup {
    let m = &d.thermal;
    let notation: Vec<Notation> = (0..3)
        .map(|a| Notation::of(m.set_points.iter().map(|s| s.b[a])))
        .collect();
    html! {
        div.table-wrap tabindex="0" role="region" aria-label="Set points" { table #thermal-set-points .numbers {
            caption { "Each set point calibrated and fused: its b with standard errors, in " (d.unit) }
            thead { tr {
                th scope="col" { "T, °C" } th scope="col" { "runs" }
                @for a in AXES { th scope="col" { "b_" (a) } th scope="col" { "u" } }
            } }
            tbody {
                @for s in &m.set_points {
                    tr {
                        th scope="row" { (celsius(s.temperature_c)) }
                        td.num { (s.runs.len()) }
                        @for a in 0..3 {
                            td.num { (notation[a].num(s.b[a])) }
                            td.num { (unc(s.b_std_errors[a])) }
                        }
                    }
                }
            }
        } }
    }
}

/// The facts both the page and the certificate state.
fn facts(d: &ThermalTriadDoc) -> Markup {
    html! {
        div { dt { "Valid from" } dd { (celsius(d.range_c[0])) " to " (celsius(d.range_c[1])) " °C (the set points' span)" } }
        div { dt { "Reference T_ref" } dd { (celsius(d.reference_c)) " °C" } }
        div { dt { "Set points" } dd { (d.thermal.set_points.len()) " (within " (d.thermal.tolerance_k) " K), " (d.runs) @if d.thermal.method == GRAVITY_MAGNITUDE { " static positions" } @else { " runs" } } }
        @if let Some(t) = &d.sensor_type { div { dt { "Sensor type" } dd { (t) } } }
        (fitted_from(&d.from_calibrations))
        @if let Some(u) = d.thermal.thermometer_std_c { div { dt { "Thermometer" } dd { "u_T = " (u) " K, in every element read at a temperature" } } }
    }
}

/// The decision's table, element by element.
fn elements_table(dec: &TriadThermalDecision) -> Markup {
    decision_table(
        dec.rule,
        "element",
        dec.elements.iter().map(|(name, j)| (name.clone(), j)),
    )
}

/// `d` as its page shows it.
pub fn page(d: &ThermalTriadDoc) -> Page<'_> {
    let m = &d.thermal;
    Page {
        id: d.id,
        sensor_id: &d.sensor_id,
        title: "Triad temperature model",
        noun: "triad temperature model",
        verdict: Some(
            html! { @if let Some(dec) = &d.decision { (badge(dec.verdict.as_str(), dec.verdict.as_str())) } },
        ),
        supersedes: d.supersedes.as_ref(),
        performed_at: &d.performed_at,
        station_id: d.station_id.as_deref(),
        received_at: &d.received_at,
        facts: html! {
            (facts(d))
            div { dt { "Degrees" } dd { (m.selection) } }
        },
        downloads: Some(html! {
            "Download: "
            @for (k, (format, label)) in EXPORTS.iter().enumerate() {
                @if k > 0 { " · " }
                a href={"/ui/calibrations/" (d.id) "/export/" (format)} { (label) }
            }
        }),
        certified: true,
        sections: html! {
            @if let Some(dec) = &d.decision {
                h2 { "Decision" }
                (elements_table(dec))
            }
            h2 { "b and S at T_ref" }
            div.table-wrap tabindex="0" role="region" aria-label="b and S at T_ref" { table #thermal-at-reference .numbers {
                caption { "b in " (d.unit) ", S in " (d.unit) " per g, at " (celsius(d.reference_c)) " °C, with standard uncertainties u" }
                thead { tr { th scope="col" { "element" } th scope="col" { "value" } th scope="col" { "u" } } }
                tbody {
                    @for e in d.kind.elements.elements().iter().filter(|e| e.name.starts_with('b') || e.name.starts_with("S_")) {
                        tr { th scope="row" { (e.name) } td.num { (num(e.value)) }
                            td.num { (e.std_error.map_or("—".into(), unc)) } }
                    }
                }
            } }
            h2 { "Polynomials" }
            (polynomials_table("element", "e(T)", m.polynomials()))
            h2 { "Set points" }
            (set_points_table(d))
        },
    }
}

/// What the fit did, in words.
fn fitted(d: &ThermalTriadDoc) -> String {
    let m = &d.thermal;
    let gravity = m.method == GRAVITY_MAGNITUDE;
    format!(
        "{} at {} temperature set points from {} to {} °C ({} {}; within {} K of a set point \
         belong to it): {}. Each element's polynomial about T_ref = {} °C fitted \
         to the set points' fused values by weighted least squares (weights 1/u²), its degree \
         chosen by partial F tests at 1 % ({}), its covariance scaled by max(1, χ²/ν) when the \
         set points scatter more than their standard errors say. The model is valid from T_min \
         to T_max only; read at a temperature T, an element's standard uncertainty is \
         √(vᵀ C v), v_d = (T − T_ref)^d{}. Compensation applies T(T) = S(T)⁻¹.",
        if gravity {
            "Static positions of the triad in unknown orientations"
        } else {
            "Tumble tests of the triad in known orientations"
        },
        m.set_points.len(),
        celsius(d.range_c[0]),
        celsius(d.range_c[1]),
        d.runs,
        if gravity { "positions" } else { "runs" },
        m.tolerance_k,
        if gravity {
            "each set point's b and S found from the gravity magnitude on its own (S \
             lower-triangular: the sensor's x axis and xy-plane define the frame, so S_xy, S_xz \
             and S_yz are zero by convention, not measured)"
        } else {
            "each set point calibrated as a triad is, each axis's row of S and element of b by \
             least squares per run and batch-estimation fusion"
        },
        celsius(d.reference_c),
        m.selection,
        match m.thermometer_std_c {
            Some(u) => format!(
                ", combined with the thermometer's u_T = {u} K times the slope |de/dT| there"
            ),
            None => String::new(),
        }
    )
}

/// Model `d` as its certificate (in context `c`) and DCC read it.
pub fn document<'a>(d: &'a ThermalTriadDoc, c: &Context) -> Document<'a> {
    let facts = html! {
        div { dt { "Sensor" } dd { strong { (d.sensor_id) } " (accelerometer triad, model over temperature)" } }
        div { dt { "Station" } dd { (d.station_id.as_deref().unwrap_or("—")) } }
        div { dt { "Place of calibration" } dd { (c.laboratory.address.as_deref().unwrap_or("the laboratory's (no address configured)")) } }
        div { dt { "Performed" } dd { (when(&d.performed_at)) } }
        div { dt { "Submitted to accelcal" } dd { (when(&d.received_at)) } }
        div { dt { "Output unit" } dd { (d.unit) } }
        (facts(d))
    };
    let caption = html! {
        "Each element's polynomial e(T) = Σ a_d (T − " (celsius(d.reference_c)) " °C)^d, valid from "
        (celsius(d.range_c[0])) " to " (celsius(d.range_c[1])) " °C: each a_d rounded to its expanded "
        "uncertainty's second significant digit, with u" sub { "c" } ", ν" sub { "eff" } ", k and p. "
        "The a_d are correlated: read the model at a temperature with its covariance (the calibration's JSON)"
    };
    Document {
        admin: Admin {
            id: d.id,
            sensor_id: &d.sensor_id,
            item: "Accelerometer triad",
            performed_at: &d.performed_at,
            item_received_at: None,
            item_condition: None,
            supersedes: d.supersedes.as_ref(),
            standards: &d.standards,
            judged: d
                .decision
                .as_ref()
                .map(|dec| super::judged(dec.rule, dec.verdict, dec.elements.values())),
            due_at: d.due_at.as_deref(),
        },
        running: format!("{} (triad temperature model)", d.sensor_id),
        quantities: quantities(d),
        printed: Printed {
            facts,
            before_method: html! {},
            method: html! { (fitted(d)) " Each set point follows " (PAPER) "." },
            label: "Triad temperature model",
            caption,
            column: Column::Element,
            after_results: html! {
                p { "At the set points, each calibrated and fused on its own (standard errors; temperatures as read):" }
                (set_points_table(d))
            },
            conformity: d.decision.as_ref().map(|dec| {
                html! {
                    p { "Decision rule: " (rule_name(dec.rule)) "; each axis's limited terms are elements of b and "
                        "S (k0 is b_m; ki, kp, ko row m of S), each judged at every set point and across the "
                        "range with its expanded uncertainty there; its worst stated." }
                    (elements_table(dec))
                }
            }),
            as_found: None,
            before_traceability: standards(&d.standards),
            computed_by: None,
        },
        dcc: DccText {
            name: "Static model of the accelerometer triad over temperature",
            description: format!(
                "Each element of b and S of the triad's model u = b + S g, output in {}, as a \
                 polynomial in temperature e(T) = Σ a_d (T − T_ref)^d about T_ref = {} °C, valid \
                 from {} to {} °C only; g in multiples of the local g (unit one), so every a_d is \
                 in the output's unit per K^d. Labels <element>_a<d>. The a_d of one element are \
                 correlated; their covariance is stated with the calibration's result. Values \
                 are rounded to the second significant digit of their expanded uncertainty.",
                d.unit,
                celsius(d.reference_c),
                celsius(d.range_c[0]),
                celsius(d.range_c[1]),
            ),
            method_name: if d.thermal.method == GRAVITY_MAGNITUDE {
                "Static positions of the triad at temperature set points, each fitted from the \
                 gravity magnitude; each element's polynomial by weighted least squares"
            } else {
                "Tumble tests of the triad in known orientations at temperature set points, \
                 each by least squares per run and batch-estimation fusion; each element's \
                 polynomial by weighted least squares"
            },
            method: fitted(d),
            reference: Some(PAPER),
            temperatures: Some(
                d.thermal
                    .set_points
                    .iter()
                    .map(|s| s.temperature_c)
                    .collect(),
            ),
            reference_c: Some(d.reference_c),
            unit: d.unit.clone(),
            results_name: "Polynomial coefficients a_d of each element of b and S over temperature",
        },
    }
}
