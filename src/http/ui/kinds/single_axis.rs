//! A single axis's calibration as its documents read it: the fused
//! coefficients of `U = Σ k·f(a)` as [`Quantity`]s (each in its
//! regressor's unit, `ki` in mA/g), and the passages only this kind
//! writes — the stand and environmental conditions, the tumble test's
//! method, the uncertainty budget, the decision and as found term by term.

pub mod page;

use maud::html;

use crate::http::ui::axis::{as_found, budget, decision};
use crate::http::ui::certificate::{Context, PAPER, standards};
use crate::http::ui::coverage::coverage_statement;
use crate::http::ui::document::{
    Admin, Column, DccText, Document, Judged, Limited, Printed, Quantity,
};
use crate::http::ui::format::term_unit;
use crate::http::ui::result::{MethodDoc, ResultDoc};
use crate::http::ui::stored::when;

/// What each term is, in words.
pub fn term_meaning(t: accelcal_core::Term) -> &'static str {
    use accelcal_core::Term;
    match t {
        Term::K0 => "bias",
        Term::Ki => "scale factor K1 (input axis)",
        Term::Kp => "pendulous-axis sensitivity (misalignment)",
        Term::Ko => "output-axis sensitivity",
        Term::Kio => "cross-coupling, input × output axis",
        Term::Kop => "cross-coupling, output × pendulous axis",
        Term::Kpi => "cross-coupling, pendulous × input axis",
        Term::Kii => "second-order non-linearity K2",
        Term::Kpp => "pendulous-axis square",
        Term::Koo => "output-axis square",
        Term::Kiii => "third-order non-linearity K3",
    }
}

/// The fused coefficients, in the model's order.
pub fn quantities(d: &ResultDoc) -> Vec<Quantity> {
    d.fused
        .coefficients
        .iter()
        .map(|(t, v)| {
            let unit = term_unit(t, &d.unit);
            Quantity {
                name: t.name().to_owned(),
                meaning: term_meaning(t).to_owned(),
                value: *v,
                std_error: d.fused.std_errors.get(t).copied(),
                expanded: d
                    .uncertainty
                    .as_ref()
                    .and_then(|u| u.terms.get(t))
                    .map(|b| b.expanded),
                covered: d.uncertainty.as_ref().and_then(|u| u.covered(t)),
                dcc_unit: unit.clone(),
                unit,
                limited: d.decision.as_ref().and_then(|dec| {
                    let j = dec.terms.get(t)?;
                    Some(Limited {
                        verdict: j.verdict.clone(),
                        value: j.value,
                        min: j.min,
                        max: j.max,
                    })
                }),
                per_kelvin: 0,
                fixed: None,
            }
        })
        .collect()
}

/// The DCC's administrative data of `d`.
pub fn admin(d: &ResultDoc) -> Admin<'_> {
    Admin {
        id: d.id,
        sensor_id: &d.sensor_id,
        item: "Accelerometer",
        performed_at: &d.performed_at,
        item_received_at: d.item_received_at.as_deref(),
        item_condition: d.item_condition.as_deref(),
        supersedes: d.supersedes.as_ref(),
        standards: &d.standards,
        judged: d.decision.as_ref().map(|dec| {
            Judged::of(
                &dec.rule,
                &dec.verdict,
                dec.terms
                    .iter()
                    .map(|(_, x)| (x.verdict.as_str(), x.value, x.min, x.max)),
            )
        }),
        due_at: d.due_at.as_deref(),
    }
}

/// Calibration `d` as its certificate (in context `c`) and DCC read it.
pub fn document<'a>(d: &'a ResultDoc, c: &Context) -> Document<'a> {
    let statement = d.uncertainty.as_ref().map(coverage_statement);
    let facts = html! {
        div { dt { "Sensor" } dd { strong { (d.sensor_id) } } }
        div { dt { "Sensor type" } dd { (d.sensor_type.as_deref().unwrap_or("none")) } }
        div { dt { "Station" } dd { (d.station_id.as_deref().unwrap_or("—")) } }
        div { dt { "Place of calibration" } dd { (c.laboratory.address.as_deref().unwrap_or("the laboratory's (no address configured)")) } }
        div { dt { "Stand" } dd { @match &d.stand {
            Some(s) => { (s.id.as_deref().unwrap_or("unnamed")) ": indexing " (s.angle_std_arcsec) "″ (1σ), gravity " (s.gravity_rel_std) " (relative, 1σ)" },
            None => "not declared (no stand contribution)",
        } } }
        div { dt { "Item received" } dd { (d.item_received_at.as_deref().map_or("not recorded".into(), when)) } }
        div { dt { "Condition on receipt" } dd { (d.item_condition.as_deref().unwrap_or("not recorded")) } }
        div { dt { "Performed" } dd { (when(&d.performed_at)) } }
        div { dt { "Submitted to accelcal" } dd { (when(&d.received_at)) } }
        div { dt { "Due" } dd {
            @if c.customer.as_ref().is_none_or(|cu| cu.due_date_agreed) {
                (d.due_at.as_deref().map_or("—".into(), when))
            } @else {
                "not stated (no due date was agreed with the customer)"
            }
        } }
        div { dt { "Output unit" } dd { (d.unit) } }
    };
    let before_method = html! {
        h2 { "Environmental conditions" }
        dl.facts {
            div { dt { "Temperature" } dd { (temperatures(d)) } }
            div { dt { "Local gravity" } dd { (local_gravity(d)) } }
        }
        (standards(&d.standards))
    };
    let method = html! {
        "Tumble test in the 1 g field on a dividing head (" (d.mount) " mount, "
        (d.positions.len()) " positions, " (d.runs.len()) " runs). The static model "
        code { "U = Σ k·f(a)" } " with terms " strong { (d.model.join(", ")) }
        " is identified from each run by least squares; the runs are fused by batch "
        "estimation (" (d.batches) " batches, inverse-variance weighting of batch means), after "
        (PAPER) ". Uncertainty after the GUM: the fused standard error, the stand's indexing "
        "error, the uncertainty of gravity and, when the lack-of-fit test finds the model short of the data, "
        "the model's own standard error, combined in quadrature and expanded"
        @if let Some(s) = &statement { (s) } "."
    };
    let caption = html! {
        "Fused coefficients, each rounded to its expanded uncertainty's second significant digit, "
        "with its combined standard uncertainty u"
        sub { "c" } ", effective degrees of freedom ν"
        sub { "eff" } ", coverage factor k and coverage probability p"
    };
    let dcc = DccText {
        name: "Static model of the accelerometer",
        description: format!(
            "Fused coefficients of the model U = Σ k·f(a), with terms {}, the output U in {} and \
             the specific force a in multiples of the local g (unit one): each coefficient is in \
             the output's unit per unit of its regressor. Values are rounded to the second \
             significant digit of their expanded uncertainty.",
            d.model.join(", "),
            d.unit
        ),
        method_name: "Tumble test in the 1 g field, least squares per run, batch-estimation fusion",
        method: format!(
            "Tumble test on a dividing head ({} mount, {} positions, {} runs), the static model \
             identified from each run by least squares and the runs fused by batch estimation ({} \
             batches, inverse-variance weighting of batch means). Uncertainty after the GUM: the \
             fused standard error, the stand's indexing error, the uncertainty of gravity and, when \
             the lack-of-fit test finds the model short of the data, the model's own standard \
             error, combined in quadrature and expanded{}.",
            d.mount,
            d.positions.len(),
            d.runs.len(),
            d.batches,
            statement.clone().unwrap_or_default()
        ),
        reference: Some(PAPER),
        temperatures: d.temperatures_c.clone(),
        reference_c: None,
        unit: d.unit.clone(),
        results_name: "Fused coefficients",
    };
    Document {
        admin: admin(d),
        running: d.sensor_id.clone(),
        quantities: quantities(d),
        printed: Printed {
            facts,
            before_method,
            method,
            label: "Fused coefficients",
            caption,
            column: Column::Term,
            after_results: budget(d),
            conformity: d.decision.is_some().then(|| decision(d)),
            as_found: d.as_found.is_some().then(|| as_found(d)),
            before_traceability: html! {},
            computed_by: Some(MethodDoc::describe(d.method.as_ref())),
        },
        dcc,
    }
}

/// The runs' temperatures as a range, or why there is none.
fn temperatures(d: &ResultDoc) -> String {
    match d.temperatures_c.as_deref() {
        Some(t) if !t.is_empty() => {
            let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let thermometer =
                d.standards
                    .iter()
                    .find(|u| u.role == "thermometer")
                    .map_or(String::new(), |u| {
                        format!(
                            ", read with {} (±{} °C, 1σ)",
                            u.standard_id,
                            u.parameters.temperature_std_c.unwrap_or(0.0)
                        )
                    });
            if lo == hi {
                format!("{lo} °C in every run{thermometer}")
            } else {
                format!("{lo} to {hi} °C over the runs{thermometer}")
            }
        }
        _ => "not recorded with the submission".into(),
    }
}

/// The local gravity value used, or what the model assumes.
fn local_gravity(d: &ResultDoc) -> String {
    match d.standards.iter().find(|u| u.role == "gravity") {
        Some(u) => format!(
            "g = {} m/s² (relative uncertainty {}, 1σ; standard {})",
            u.parameters
                .gravity_m_s2
                .map_or("—".into(), |g| g.to_string()),
            u.parameters
                .gravity_rel_std
                .map_or("—".into(), |r| r.to_string()),
            u.standard_id
        ),
        None => "not stated: the positions are in units of the local g (1 g)".into(),
    }
}
