//! The printable certificate of a triad's calibration (issue 30): the same
//! document as a single axis's ([`super::certificate`]: laboratory, item and
//! customer, review and signatures, the submission's SHA-256, the version
//! and the certificate's own URL, the A4 print layout), with the triad's
//! results: `b` and `S` element by element, each rounded to its expanded
//! uncertainty (GUM 7.2.6) where the method gives one (known orientations:
//! each axis's single-axis budget; the gravity magnitude: the fit's budget,
//! with `S`'s elements above the diagonal stated as zero by the frame
//! convention), else with its standard error; `T` for compensation; the
//! decision element by element and as found.

use maud::{Markup, html};

use super::badge;
use super::certificate::{
    Context, Frame, PAPER, customer_and_item, frame, standards, traceability, verification,
};
use super::format::{dof, factor, num, percent, unc, value_and_uncertainty};
use super::result::Covered;
use super::stored::when;
use super::triad_result::TriadDoc;
use crate::store::AXES;

/// One row of the results: element, value, standard error, `u_c`,
/// `ν_eff`, `k`, `p`, U, unit.
fn row(
    name: &str,
    v: f64,
    se: Option<f64>,
    u: Option<f64>,
    c: Option<Covered>,
    unit: &str,
) -> Markup {
    let combined = c.map(|c| c.combined).filter(|x| x.is_finite());
    let (value, expanded) = match u {
        Some(u) => {
            let (v, u) = value_and_uncertainty(v, u);
            (v, u)
        }
        None => (num(v), "—".into()),
    };
    html! {
        tr data-element=(name) {
            th scope="row" { (name) }
            td.num { (value) }
            td.num { (se.map_or("—".into(), unc)) }
            td.num { (combined.map_or("—".into(), unc)) }
            td.num { (c.map_or("—".into(), |c| dof(c.effective_dof))) }
            td.num { (c.filter(|_| u.is_some()).map_or("—".into(), |c| factor(c.k))) }
            td.num { (c.filter(|_| u.is_some()).map_or("—".into(), |c| percent(c.p))) }
            td.num { (expanded) }
            td { (unit) }
        }
    }
}

/// The certificate of triad `d`.
pub fn render(d: &TriadDoc, c: &Context) -> Markup {
    let known = d.method == "known_orientations";
    let per_g = format!("{} per g", d.unit);
    let body = html! {
                    h2 { "Item and calibration" }
                    dl.facts {
                        (customer_and_item(c))
                        div { dt { "Sensor" } dd { strong { (d.sensor_id) } " (accelerometer triad)" } }
                        div { dt { "Station" } dd { (d.station_id.as_deref().unwrap_or("—")) } }
                        div { dt { "Place of calibration" } dd { (c.laboratory.address.as_deref().unwrap_or("the laboratory's (no address configured)")) } }
                        div { dt { "Performed" } dd { (when(&d.performed_at)) } }
                        div { dt { "Submitted to accelcal" } dd { (when(&d.received_at)) } }
                        div { dt { "Output unit" } dd { (d.unit) } }
                    }
                    h2 { "Method" }
                    p {
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
                    }
                    h2 { "Results" }
                    div.table-wrap tabindex="0" role="region" aria-label="Triad results" {
                        table #certificate-results {
                            caption {
                                "b and S by element, each rounded to its expanded uncertainty's second significant digit where one is stated, "
                                "with its combined standard uncertainty u" sub { "c" } ", effective degrees of freedom ν" sub { "eff" }
                                ", coverage factor k and coverage probability p"
                            }
                            thead { tr {
                                th scope="col" { "Element" }
                                th scope="col" .num { "Value" }
                                th scope="col" .num { "Standard error" }
                                th scope="col" .num { "u" sub { "c" } }
                                th scope="col" .num { "ν" sub { "eff" } }
                                th scope="col" .num { "k" }
                                th scope="col" .num { "p" }
                                th scope="col" .num { "Expanded U" }
                                th scope="col" { "Unit" }
                            } }
                            tbody {
                                @for (m, axis) in AXES.iter().enumerate() {
                                    (row(&format!("b_{axis}"), d.b[m], d.b_std_errors.map(|e| e[m]), d.b_expanded.map(|e| e[m]), d.covered(&format!("b_{axis}")), &d.unit))
                                }
                                @for (m, r) in AXES.iter().enumerate() {
                                    @for (k, col) in AXES.iter().enumerate() {
                                        @if !known && k > m {
                                            tr data-element={"S_" (r) (col)} {
                                                th scope="row" { "S_" (r) (col) }
                                                td.num { "0" } td.num { "—" } td.num { "—" } td.num { "—" } td.num { "—" } td.num { "—" } td.num { "—" }
                                                td { "by the frame convention" }
                                            }
                                        } @else {
                                            (row(&format!("S_{r}{col}"), d.s[m][k], d.s_std_errors.map(|e| e[m][k]), d.s_expanded.map(|e| e[m][k]), d.covered(&format!("S_{r}{col}")), &per_g))
                                        }
                                    }
                                }
                                @if let Some(s2) = d.s2 {
                                    @for (m, axis) in AXES.iter().enumerate() {
                                        (row(&format!("S2_{axis}"), s2[m], d.s2_std_errors.map(|e| e[m]), d.s2_expanded.map(|e| e[m]), d.covered(&format!("S2_{axis}")), &format!("{} per g²", d.unit)))
                                    }
                                }
                            }
                        }
                    }
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
                    @if let Some(dec) = &d.decision {
                        h2 { "Conformity" }
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
                    @if let Some(a) = &d.as_found {
                        h2 { "As found" }
                        p { "With the previous calibration " code { (a.previous_calibration_id) } ", this test's positions come out with a largest error of " (num(a.max_abs_error_g)) " g." }
                    }
                    (standards(&d.standards))
                    (traceability(&d.standards))
                    (verification(c, None))
    };
    frame(
        &Frame {
            id: &d.id,
            running: &format!("{} (triad)", d.sensor_id),
            supersedes: d.supersedes.as_ref(),
            verdict: d.decision.as_ref().map(|dec| dec.verdict.as_str()),
        },
        c,
        body,
    )
}
