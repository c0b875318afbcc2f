//! A temperature model as its documents read it (issue 45 item 4): every
//! coefficient's polynomial `c(T) = Σ a_d (T − T_ref)^d` as one
//! [`Quantity`] per `a_d` — in the coefficient's unit per K^d (`V/g/K`;
//! D-SI `\volt\kelvin\tothe{-1}`, the specific force a ratio) — and the
//! passages only this kind writes: the set points and the fit, the table
//! of each set point's fused coefficients, the decision over the range.
//!
//! **Uncertainty of an `a_d`.** `u(a_d)` is the square root of the
//! polynomial's covariance diagonal, `(XᵀWX)⁻¹ · max(1, χ²/ν)`; its
//! expanded uncertainty `U = k · u(a_d)` at the certificate's coverage
//! probability (the sensor type's, or 95.45 %; or the type's factor),
//! `k` for `ν = N − D − 1` when the Birge ratio
//! inflated the covariance (the set points' scatter set it), for infinite
//! degrees of freedom otherwise — as the decision forms `U` across the
//! range. The `a_d` are correlated: what a user reads at a temperature is
//! `√(vᵀ C v)` (and the thermometer's term), which the certificate states
//! in words and the calibration's JSON holds in full (`thermal.coefficients.
//! <term>.covariance`).
//!
//! **The DCC** lists the `a_d` as `si:real` (label `<term>_a<d>`), and the
//! range as the influence condition — the lowest and highest set point
//! and `T_ref`, with the thermometer's standard uncertainty when one was
//! named.

pub mod page;
pub mod triad;

use accelcal_core::coverage::Coverage;
use accelcal_core::thermal::Polynomial;
use maud::html;

use crate::domain::thermal::decision::ThermalTermDecision;
use crate::http::ui::certificate::{Context, PAPER, standards};
use crate::http::ui::document::{Admin, Column, DccText, Document, Judged, Printed, Quantity};
use crate::http::ui::format::term_unit;
use crate::http::ui::kinds::single_axis::term_meaning;
use crate::http::ui::result::Covered;
use crate::http::ui::stored::when;
use crate::http::ui::thermal_result::ThermalDoc;
use page::{celsius, rule_name, set_points_table, terms_table};

/// `^d` as a unit's exponent is printed (`K`, `K²`, `K³`).
fn kelvin(d: usize) -> &'static str {
    ["", "/K", "/K²", "/K³"][d.min(3)]
}

/// What `a_d` of a coefficient that is `meaning` is, about `reference_c`.
fn described(meaning: &str, d: usize, reference_c: f64) -> String {
    let at = celsius(reference_c);
    match d {
        0 => format!("{meaning}: its value at T_ref = {at} °C (a_0)"),
        1 => format!("{meaning}: its change per kelvin at T_ref = {at} °C (a_1)"),
        _ => format!("{meaning}: the coefficient of (T − {at} °C)^{d} (a_{d})"),
    }
}

/// Every polynomial's `a_d`, coefficient by coefficient in the model's
/// order, lowest degree first.
pub fn quantities(d: &ThermalDoc) -> Vec<Quantity> {
    let each = d.thermal.coefficients.iter().map(|(term, p)| {
        let (name, meaning) = (term.name().to_owned(), term_meaning(term).to_owned());
        (name, meaning, term_unit(term, &d.unit), p)
    });
    polynomials(each, d.coverage)
}

/// The `a_d` of each `(name, meaning, unit, polynomial)`, lowest degree
/// first, expanded at `coverage` (module doc).
pub fn polynomials<'a>(
    each: impl Iterator<Item = (String, String, String, &'a Polynomial)>,
    coverage: Coverage,
) -> Vec<Quantity> {
    let mut out = Vec::new();
    for (name, meaning, unit, p) in each {
        let dof = (p.inflation > 1.0).then_some(p.dof as u64);
        let at = coverage.at(dof);
        for (j, (&a, &u)) in p.coefficients.iter().zip(&p.std_uncertainties).enumerate() {
            let unit = format!("{unit}{}", kelvin(j));
            out.push(Quantity {
                name: format!("{name}_a{j}"),
                meaning: described(&meaning, j, p.reference_c),
                value: a,
                std_error: Some(u),
                expanded: Some(at.factor * u),
                covered: Some(Covered {
                    combined: u,
                    effective_dof: Some(dof),
                    k: at.factor,
                    p: at.probability,
                }),
                dcc_unit: unit.clone(),
                unit,
                per_kelvin: j as i32,
                limited: None,
                fixed: None,
            });
        }
    }
    out
}

/// The DCC's administrative data of `d`.
pub fn admin(d: &ThermalDoc) -> Admin<'_> {
    Admin {
        id: d.id,
        sensor_id: &d.sensor_id,
        item: "Accelerometer",
        performed_at: &d.performed_at,
        item_received_at: None,
        item_condition: None,
        supersedes: d.supersedes.as_ref(),
        standards: &d.standards,
        judged: d
            .decision
            .as_ref()
            .map(|dec| judged(dec.rule, dec.verdict, dec.terms.iter().map(|(_, t)| t))),
        due_at: d.due_at.as_deref(),
    }
}

/// The statement of conformity of a model judged by `rule` to `verdict`
/// over `terms` (a single axis's coefficients or a triad's elements):
/// each by its worst judgement.
pub fn judged<'a>(
    rule: accelcal_core::decision::Rule,
    verdict: accelcal_core::decision::Verdict,
    terms: impl Iterator<Item = &'a ThermalTermDecision>,
) -> Judged<'static> {
    Judged::of(
        rule_name(rule),
        verdict.as_str(),
        terms.map(|t| (t.worst.verdict.as_str(), t.worst.value, t.min, t.max)),
    )
}

/// What the fit did, in words: set points, weights, degree and inflation.
fn fitted(d: &ThermalDoc) -> String {
    let m = &d.thermal;
    format!(
        "Tumble tests at {} temperature set points from {} to {} °C ({} runs; runs within {} K \
         of a set point belong to it): each set point identified by least squares per run and \
         fused by batch estimation on its own. Each coefficient's polynomial about T_ref = {} °C \
         fitted to the set points' fused values by weighted least squares (weights 1/u², u the \
         set point's standard error), its degree chosen by partial F tests at 1 % ({}), its \
         covariance scaled by max(1, χ²/ν) when the set points scatter more than their standard \
         errors say. The model is valid from T_min to T_max only. Read at a temperature T, a \
         coefficient's standard uncertainty is √(vᵀ C v), v_d = (T − T_ref)^d, through the \
         polynomial's covariance C{}.",
        m.set_points.len(),
        celsius(d.range_c[0]),
        celsius(d.range_c[1]),
        d.runs,
        m.tolerance_k,
        celsius(d.reference_c),
        m.selection,
        match m.thermometer_std_c {
            Some(u) => format!(
                ", combined with the thermometer's u_T = {u} K times the slope |dc/dT| there"
            ),
            None => String::new(),
        }
    )
}

/// Model `d` as its certificate (in context `c`) and DCC read it.
pub fn document<'a>(d: &'a ThermalDoc, c: &Context) -> Document<'a> {
    let m = &d.thermal;
    let facts = html! {
        div { dt { "Sensor" } dd { strong { (d.sensor_id) } " (model over temperature)" } }
        div { dt { "Station" } dd { (d.station_id.as_deref().unwrap_or("—")) } }
        div { dt { "Place of calibration" } dd { (c.laboratory.address.as_deref().unwrap_or("the laboratory's (no address configured)")) } }
        div { dt { "Performed" } dd { (when(&d.performed_at)) } }
        div { dt { "Submitted to accelcal" } dd { (when(&d.received_at)) } }
        div { dt { "Output unit" } dd { (d.unit) } }
        div { dt { "Valid from" } dd { (celsius(d.range_c[0])) " to " (celsius(d.range_c[1])) " °C (the set points' span)" } }
        div { dt { "Reference T_ref" } dd { (celsius(d.reference_c)) " °C" } }
        @if let Some(u) = m.thermometer_std_c { div { dt { "Thermometer" } dd { "u_T = " (u) " K" } } }
    };
    let caption = html! {
        "Each coefficient's polynomial c(T) = Σ a_d (T − " (celsius(d.reference_c)) " °C)^d, valid from "
        (celsius(d.range_c[0])) " to " (celsius(d.range_c[1])) " °C: each a_d rounded to its expanded "
        "uncertainty's second significant digit, with u"
        sub { "c" } " (the polynomial's covariance), ν" sub { "eff" } ", k and p. The a_d are "
        "correlated: read the model at a temperature with its covariance (the calibration's JSON)"
    };
    let after_results = html! {
        p { "At the set points, each identified and fused on its own (standard errors; temperatures as read):" }
        (set_points_table(d))
    };
    let conformity = d.decision.as_ref().map(|dec| {
        html! {
            p { "Decision rule: " (rule_name(dec.rule)) "; every limited coefficient judged at each set point and across the "
                "range with its expanded uncertainty there; its worst stated." }
            (terms_table(dec))
        }
    });
    Document {
        admin: admin(d),
        running: format!("{} (temperature model)", d.sensor_id),
        quantities: quantities(d),
        printed: Printed {
            facts,
            before_method: html! {},
            method: html! { (fitted(d)) " Each set point follows " (PAPER) "." },
            label: "Temperature model",
            caption,
            column: Column::Term,
            after_results,
            conformity,
            as_found: None,
            before_traceability: standards(&d.standards),
            computed_by: None,
        },
        dcc: dcc_text(d),
    }
}

/// The DCC measurement result's texts of model `d`.
fn dcc_text(d: &ThermalDoc) -> DccText {
    DccText {
        name: "Static model of the accelerometer over temperature",
        description: format!(
            "Each coefficient c of the static model, output in {}, as a polynomial in temperature \
             c(T) = Σ a_d (T − T_ref)^d about T_ref = {} °C, valid from {} to {} °C only. a_d is \
             in the coefficient's unit per K^d, the specific force a ratio (unit one); labels \
             <term>_a<d>. The a_d of one coefficient are correlated; their covariance is stated \
             with the calibration's result. Values are rounded to the second significant digit of \
             their expanded uncertainty.",
            d.unit,
            celsius(d.reference_c),
            celsius(d.range_c[0]),
            celsius(d.range_c[1]),
        ),
        method_name: "Tumble tests at temperature set points, each by least squares per run and \
                      batch-estimation fusion; each coefficient's polynomial by weighted least \
                      squares",
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
        results_name: "Polynomial coefficients a_d of each coefficient over temperature",
    }
}
