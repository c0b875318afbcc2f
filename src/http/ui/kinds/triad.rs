//! A triad's calibration as its documents read it (issue 30): every
//! element of `b`, `S` (and `S2`) as a [`Quantity`] — from the gravity
//! magnitude, `S_xy`, `S_xz` and `S_yz` are fixed at zero by the frame
//! convention, listed as such on the printed certificate and left out of
//! the DCC — and the passages only this kind writes: the method (known
//! orientations, or the gravity magnitude), `T = S⁻¹` for compensation,
//! the decision element by element and as found.
//!
//! **Units.** `u = b + S g` with `g` the specific force in multiples of the
//! local g (unit one), so `b`, `S` and `S2` are all in the output's unit,
//! as a single axis's `k0` and `ki` are (the DCC's unit); the printed
//! certificate reads `S` per g and `S2` per g². `T = S⁻¹`, what firmware
//! applies, is derived from `S`, not measured: the description names it and
//! the calibration's exports carry it.

pub mod page;

use maud::html;

use crate::domain::triad::{FIXED_BY_CONVENTION, KNOWN_ORIENTATIONS};
use crate::http::ui::badge;
use crate::http::ui::certificate::{Context, PAPER, standards};
use crate::http::ui::document::{
    Admin, Column, DccText, Document, Judged, Limited, Printed, Quantity,
};
use crate::http::ui::format::{num, unc};
use crate::http::ui::stored::when;
use crate::http::ui::triad_result::TriadDoc;
use crate::store::AXES;

/// What element `matrix` of axis `m` (column `k` for `S`) is.
pub fn meaning(matrix: &str, m: usize, k: usize) -> String {
    let axis = AXES[m];
    match matrix {
        "b" => format!("bias of the {axis} axis"),
        "S2" => format!("second-order coefficient of the {axis} axis (its output per g² along it)"),
        _ if k == m => format!("scale factor of the {axis} axis"),
        _ => format!(
            "sensitivity of the {axis} axis to specific force along {} (misalignment)",
            AXES[k]
        ),
    }
}

/// The elements in order: `b`, `S` by rows, `S2`.
pub fn quantities(d: &TriadDoc) -> Vec<Quantity> {
    let known = d.method == KNOWN_ORIENTATIONS;
    let element = |matrix: &str, m: usize, k: usize, unit: String| {
        let name = match matrix {
            "S" => format!("S_{}{}", AXES[m], AXES[k]),
            _ => format!("{matrix}_{}", AXES[m]),
        };
        let (value, std_error, expanded) = match matrix {
            "b" => (
                d.b[m],
                d.b_std_errors.map(|e| e[m]),
                d.b_expanded.map(|e| e[m]),
            ),
            "S" => (
                d.s[m][k],
                d.s_std_errors.map(|e| e[m][k]),
                d.s_expanded.map(|e| e[m][k]),
            ),
            _ => (
                d.s2.map_or(0.0, |s2| s2[m]),
                d.s2_std_errors.map(|e| e[m]),
                d.s2_expanded.map(|e| e[m]),
            ),
        };
        Quantity {
            meaning: meaning(matrix, m, k),
            value,
            std_error,
            expanded,
            covered: d.covered(&name),
            unit,
            dcc_unit: d.unit.clone(),
            limited: d.decision.as_ref().and_then(|dec| {
                let j = dec.elements.get(&name)?;
                Some(Limited {
                    verdict: j.verdict.clone(),
                    value: j.value,
                    min: j.min,
                    max: j.max,
                })
            }),
            per_kelvin: 0,
            fixed: (matrix == "S" && !known && FIXED_BY_CONVENTION.contains(&(m, k)))
                .then_some("by the frame convention"),
            name,
        }
    };
    let mut out: Vec<Quantity> = (0..3).map(|m| element("b", m, m, d.unit.clone())).collect();
    for m in 0..3 {
        for k in 0..3 {
            out.push(element("S", m, k, format!("{} per g", d.unit)));
        }
    }
    if d.s2.is_some() {
        out.extend((0..3).map(|m| element("S2", m, m, format!("{} per g²", d.unit))));
    }
    out
}

/// The DCC's administrative data of `d`.
pub fn admin(d: &TriadDoc) -> Admin<'_> {
    Admin {
        id: d.id,
        sensor_id: &d.sensor_id,
        item: "Accelerometer triad",
        performed_at: &d.performed_at,
        item_received_at: None,
        item_condition: None,
        supersedes: d.supersedes.as_ref(),
        standards: &d.standards,
        judged: d.decision.as_ref().map(|dec| {
            Judged::of(
                &dec.rule,
                &dec.verdict,
                dec.elements
                    .values()
                    .map(|e| (e.verdict.as_str(), e.value, e.min, e.max)),
            )
        }),
        due_at: d.due_at.as_deref(),
    }
}

/// Triad `d` as its certificate (in context `c`) and DCC read it.
pub fn document<'a>(d: &'a TriadDoc, c: &Context) -> Document<'a> {
    let known = d.method == KNOWN_ORIENTATIONS;
    let facts = html! {
        div { dt { "Sensor" } dd { strong { (d.sensor_id) } " (accelerometer triad)" } }
        div { dt { "Station" } dd { (d.station_id.as_deref().unwrap_or("—")) } }
        div { dt { "Place of calibration" } dd { (c.laboratory.address.as_deref().unwrap_or("the laboratory's (no address configured)")) } }
        div { dt { "Performed" } dd { (when(&d.performed_at)) } }
        div { dt { "Submitted to accelcal" } dd { (when(&d.received_at)) } }
        div { dt { "Output unit" } dd { (d.unit) } }
    };
    let method = html! {
        "The triad's static model " code { (d.model) } " (bias b, scale-and-misalignment S, "
        "specific force g in g in the sensor's body frame; compensation " code { "g = T (u − b)" }
        ", T = S⁻¹). "
        @if known {
            "The orientations were known (" (d.residuals.len()) " positions): each axis's row of S and "
            "its element of b are that axis's single-axis calibration over the shared positions, "
            "identified per run by least squares and fused by batch estimation after " (PAPER)
            ". Uncertainty after the GUM per axis: the fused standard error, the stand's indexing "
            "error, the uncertainty of gravity and, when the lack-of-fit test finds the model short, "
            "the model's own standard error, combined in quadrature and expanded"
            (d.statement()) "."
        } @else {
            "The orientations were not known (" (d.residuals.len()) " static positions): b and a "
            "lower-triangular T were found from the gravity magnitude by Levenberg–Marquardt "
            "(the sensor's x axis defines the frame's x axis, its xy-plane the frame's xy-plane, "
            "so S_xy, S_xz and S_yz are zero by this convention, not measured). "
            @if d.expanded() {
                "Uncertainty after the GUM per element: the fit's standard error (from its Jacobian, "
                "the residuals' scatter on " (d.fit.as_ref().map_or(0, |f| f.degrees_of_freedom)) " degrees of freedom; "
                "S's propagated from T's covariance) and the uncertainty of gravity, combined in "
                "quadrature and expanded" (d.statement()) ". "
                "The orientations' own errors do not enter: the fit does not use them."
            } @else {
                "With exactly nine positions the fit has no degree of freedom left: no standard error "
                "or expanded uncertainty is stated."
            }
        }
    };
    let caption = html! {
        "b and S by element, each rounded to its expanded uncertainty's second significant digit where one is stated, "
        "with its combined standard uncertainty u" sub { "c" } ", effective degrees of freedom ν" sub { "eff" }
        ", coverage factor k and coverage probability p"
    };
    let t = html! {
        p { "For compensation, T = S⁻¹ (g per " (d.unit) ", rows by axis):" }
        div.table-wrap tabindex="0" role="region" aria-label="T" {
            table #certificate-t {
                thead { tr { th scope="col" { "row" } @for a in AXES { th scope="col" .num { "T·" (a) } } } }
                tbody {
                    @for (m, r) in AXES.iter().enumerate() {
                        tr { th scope="row" { "T_" (r) } @for k in 0..3 { td.num { (num(d.t[m][k])) } } }
                    }
                }
            }
        }
    };
    let conformity = d.decision.as_ref().map(|dec| {
        html! {
            p { "Decision rule: " (dec.rule) "; each element judged with its expanded uncertainty. Verdict " (badge(&dec.verdict, &dec.verdict)) }
            table #certificate-decision {
                thead { tr { th { "Element" } th.num { "Value" } th.num { "U" } th.num { "Min" } th.num { "Max" } th { "Verdict" } } }
                tbody {
                    @for (name, e) in &dec.elements {
                        tr { th scope="row" { (name) } td.num { (num(e.value)) } td.num { (unc(e.expanded)) }
                            td.num { (e.min.map_or("—".into(), num)) } td.num { (e.max.map_or("—".into(), num)) }
                            td { (badge(&e.verdict, &e.verdict)) } }
                    }
                }
            }
        }
    });
    let as_found = d.as_found.as_ref().map(|a| {
        html! {
            p { "With the previous calibration " code { (a.previous_calibration_id) } ", this test's positions come out with a largest error of " (num(a.max_abs_error_g)) " g." }
        }
    });
    Document {
        admin: admin(d),
        running: format!("{} (triad)", d.sensor_id),
        quantities: quantities(d),
        printed: Printed {
            facts,
            before_method: html! {},
            method,
            label: "Triad results",
            caption,
            column: Column::Element,
            after_results: t,
            conformity,
            as_found,
            before_traceability: standards(&d.standards),
            computed_by: None,
        },
        dcc: dcc_text(d),
    }
}

/// The DCC measurement result's texts of triad `d`.
fn dcc_text(d: &TriadDoc) -> DccText {
    let known = d.method == KNOWN_ORIENTATIONS;
    let statement = d.statement();
    let model = if d.s2.is_some() {
        "u = b + S g + S2 ⊙ g² (S2_m g_m² on axis m)"
    } else {
        "u = b + S g"
    };
    let description = format!(
        "The triad's static model {model}: u the three outputs in {}, g the specific force in the \
         sensor's body frame in multiples of the local g (unit one), so b, S{} are in the output's \
         unit; row m of S is axis m. Compensation applies T = S⁻¹ (g = T (u − b)), derived from S \
         and carried by the calibration's exports. {}Values are rounded to the second significant \
         digit of their expanded uncertainty.",
        d.unit,
        if d.s2.is_some() { " and S2" } else { "" },
        if known {
            ""
        } else {
            "The sensor's x axis defines the frame's x axis and its xy-plane the frame's xy-plane, \
             so S_xy, S_xz and S_yz are zero by this convention: not measured, not listed. "
        }
    );
    let method = if known {
        format!(
            "Tumble test in {} known orientations: each axis's row of S and element of b are that \
             axis's single-axis calibration over the shared positions, identified per run by least \
             squares and fused by batch estimation. Uncertainty after the GUM per axis: the fused \
             standard error, the stand's indexing error, the uncertainty of gravity and, when the \
             lack-of-fit test finds the model short of the data, the model's own standard error, \
             combined in quadrature and expanded{}.",
            d.residuals.len(),
            statement
        )
    } else {
        format!(
            "Multi-position test in {} static positions of unknown orientation: b and a \
             lower-triangular T = S⁻¹ found from the gravity magnitude (‖T (ū − b)‖ = 1) by \
             Levenberg–Marquardt. Uncertainty after the GUM per element: the fit's standard error \
             (its Jacobian, the residuals' scatter on {} degrees of freedom; S's propagated from T's \
             covariance) and the uncertainty of gravity, combined in quadrature and expanded{}; the \
             orientations' own errors do not enter.",
            d.residuals.len(),
            d.fit.as_ref().map_or(0, |f| f.degrees_of_freedom),
            if d.expanded() {
                statement
            } else {
                " (none: no degree of freedom left)".to_owned()
            }
        )
    };
    DccText {
        name: "Static model of the accelerometer triad",
        description,
        method_name: if known {
            "Tumble test in known orientations, each axis by least squares per run and \
             batch-estimation fusion"
        } else {
            "Multi-position calibration from the gravity magnitude (Levenberg–Marquardt)"
        },
        method,
        reference: known.then_some(PAPER),
        temperatures: None,
        reference_c: None,
        unit: d.unit.clone(),
        results_name: "Bias b and scale-and-misalignment matrix S",
    }
}
