//! A triad's calibration on its page (issue 30): `b`, `S` and `T` with
//! their standard errors, the expanded uncertainties and how each was
//! formed, the scale factors and non-orthogonality, the fit (unknown
//! orientations) and the residuals per position, the decision element by
//! element, and the firmware files to download
//! (`GET /ui/calibrations/{id}/export/{format}`).

use maud::{Markup, html};

use crate::domain::triad::KNOWN_ORIENTATIONS;
use crate::http::ui::badge;
use crate::http::ui::document::Page;
use crate::http::ui::format::{Notation, num, unc};
use crate::http::ui::stored::when;
use crate::http::ui::triad_result::{ElementDecisionDoc, TriadDoc};
use crate::store::AXES;

/// The firmware files offered, with their labels.
const EXPORTS: [(&str, &str); 4] = [
    ("json", "JSON"),
    ("c", "C header"),
    ("px4", "PX4 parameters"),
    ("ardupilot", "ArduPilot parameters"),
];

/// A vector (or a matrix's row) `name` of columns `col·x`, `col·y`,
/// `col·z` with standard errors beside each value, each column in its
/// notation (`values`, `errors`), each cell labelled for narrow screens.
fn vector(
    name: &str,
    col: &str,
    v: &[f64; 3],
    e: Option<&[f64; 3]>,
    (values, errors): ([Notation; 3], [Notation; 3]),
) -> Markup {
    html! {
        tr {
            th scope="row" { (name) }
            @for (k, x) in v.iter().enumerate() {
                td.num data-label={(col) "·" (AXES[k])} { (values[k].num(*x)) }
                td.num data-label={"u of " (col) "·" (AXES[k])} { (e.map_or("—".into(), |e| errors[k].unc(e[k]))) }
            }
        }
    }
}

/// The notations of the columns of `rows` and of their errors.
fn columns(rows: &[&[f64; 3]], errors: Option<&[&[f64; 3]]>) -> ([Notation; 3], [Notation; 3]) {
    let of = |rows: &[&[f64; 3]], k: usize| Notation::of(rows.iter().map(|r| r[k]));
    (
        [0, 1, 2].map(|k| of(rows, k)),
        [0, 1, 2].map(|k| errors.map_or(Notation::Scientific, |e| of(e, k))),
    )
}

/// The notations of a single row's columns: each value its own.
fn row_columns(v: &[f64; 3], e: Option<&[f64; 3]>) -> ([Notation; 3], [Notation; 3]) {
    columns(&[v], e.map(|e| [e]).as_ref().map(|e| &e[..]))
}

fn matrix(caption: &str, name: &str, m: &[[f64; 3]; 3], e: Option<&[[f64; 3]; 3]>) -> Markup {
    let rows: Vec<&[f64; 3]> = m.iter().collect();
    let errors: Option<Vec<&[f64; 3]>> = e.map(|e| e.iter().collect());
    let notation = columns(&rows, errors.as_deref());
    html! {
        div.table-wrap tabindex="0" role="region" aria-label=(name) { table #{"triad-" (name)} .numbers .cards {
            caption { (caption) }
            thead { tr {
                th scope="col" { "row" }
                @for axis in AXES { th scope="col" { (name) "·" (axis) } th scope="col" { "u" } }
            } }
            tbody {
                @for (r, axis) in AXES.iter().enumerate() {
                    (vector(&format!("{name}_{axis}"), name, &m[r], e.map(|e| &e[r]), notation))
                }
            }
        } }
    }
}

/// Triad `d` as its page shows it.
pub fn page(d: &TriadDoc) -> Page<'_> {
    let known = d.method == KNOWN_ORIENTATIONS;
    Page {
        id: d.id,
        sensor_id: &d.sensor_id,
        title: "Triad calibration",
        noun: "triad calibration",
        verdict: None,
        supersedes: d.supersedes.as_ref(),
        performed_at: &d.performed_at,
        station_id: d.station_id.as_deref(),
        received_at: &d.received_at,
        facts: html! {
            div { dt { "Model" } dd { (d.model) @if d.s2.is_none() { "; compensation g = T (u − b), T = S⁻¹" } @else { "; compensation by Newton's iteration from T (u − b)" } } }
            div { dt { "Method" } dd {
                @if known { "known orientations: each axis identified and fused by the single-axis method" }
                @else { "unknown orientations: b and T from the gravity magnitude (Levenberg–Marquardt)" }
            } }
            div { dt { "Unit" } dd { (d.unit) " (b); " (d.unit) " per g (S)" } }
            @if let Some(t) = d.temperature_c { div { dt { "Temperature" } dd { (crate::http::ui::kinds::thermal::page::celsius(t)) " °C (the readings' mean, all within 0.5 K)" } } }
            @for u in &d.standards {
                div { dt { "Standard (" (u.role) ")" } dd {
                    (u.standard_id) ", " (u.description) ": certificate " (u.certificate.number)
                    " of " (u.certificate.issued_by) ", due " (when(&u.due_at.to_string()))
                } }
            }
        },
        certified: true,
        downloads: Some(html! {
            "Download: "
            @for (k, (format, label)) in EXPORTS.iter().enumerate() {
                @if k > 0 { " · " }
                a href={"/ui/calibrations/" (d.id) "/export/" (format)} { (label) }
            }
        }),
        sections: html! {
        @if let Some(dec) = &d.decision {
            h2 { "Decision " (badge(&dec.verdict, &dec.verdict)) }
            div.table-wrap tabindex="0" role="region" aria-label="Decision" { table #triad-decision .numbers {
                caption { (dec.rule) " rule; each element judged with its expanded uncertainty U" }
                thead { tr {
                    th scope="col" { "element" } th scope="col" { "value" } th scope="col" { "U" }
                    th scope="col" { "min" } th scope="col" { "max" } th scope="col" { "verdict" }
                } }
                @let of = |f: fn(&ElementDecisionDoc) -> Option<f64>| Notation::of(dec.elements.values().filter_map(f));
                @let (value, u, min, max) = (of(|e| Some(e.value)), of(|e| Some(e.expanded)), of(|e| e.min), of(|e| e.max));
                tbody {
                    @for (name, e) in &dec.elements {
                        tr data-element=(name) {
                            th scope="row" { (name) }
                            td.num { (value.num(e.value)) } td.num { (u.unc(e.expanded)) }
                            td.num { (e.min.map_or("—".into(), |x| min.num(x))) } td.num { (e.max.map_or("—".into(), |x| max.num(x))) }
                            td { (badge(&e.verdict, &e.verdict)) }
                        }
                    }
                }
            } }
        }
        @if let Some(n) = &d.decision_note { p.notice role="note" { (n) } }
        @if let Some(a) = &d.as_found {
            p #as-found {
                "As found with the previous calibration "
                a href={"/ui/calibrations/" (a.previous_calibration_id)} { code { (a.previous_calibration_id) } }
                ": largest error " (num(a.max_abs_error_g)) " g"
            }
        }
        h2 { "Bias and matrices" }
        div.table-wrap tabindex="0" role="region" aria-label="b" { table #triad-b .numbers .cards {
            caption { "Bias b, " (d.unit) ", with standard errors u" }
            thead { tr { th scope="col" { "vector" } @for axis in AXES { th scope="col" { "b·" (axis) } th scope="col" { "u" } } } }
            tbody { (vector("b", "b", &d.b, d.b_std_errors.as_ref(), row_columns(&d.b, d.b_std_errors.as_ref()))) }
        } }
        (matrix("Scale and misalignment S (rows by axis), with standard errors u", "S", &d.s, d.s_std_errors.as_ref()))
        @if let Some(s2) = &d.s2 {
            div.table-wrap tabindex="0" role="region" aria-label="S2" { table #triad-S2 .numbers .cards {
                caption { "Second-order terms S2 (" (d.unit) " per g², u_m += S2_m g_m²), with standard errors u" }
                thead { tr { th scope="col" { "vector" } @for axis in AXES { th scope="col" { "S2·" (axis) } th scope="col" { "u" } } } }
                tbody { (vector("S2", "S2", s2, d.s2_std_errors.as_ref(), row_columns(s2, d.s2_std_errors.as_ref()))) }
            } }
        }
        @if let (Some(bu), Some(su)) = (&d.b_expanded, &d.s_expanded) {
            (matrix(&format!("Expanded uncertainties U of S; of b: {}, {}, {}",
                unc(bu[0]), unc(bu[1]), unc(bu[2])), "U", su, None))
            @if let Some(cov) = &d.coverage {
                div.table-wrap tabindex="0" role="region" aria-label="Coverage" { table #triad-coverage .numbers {
                    caption { "Each element expanded" (d.statement()) }
                    thead { tr {
                        th scope="col" { "element" } th scope="col" { "u" sub { "c" } }
                        th scope="col" { "ν" sub { "eff" } } th scope="col" { "k" } th scope="col" { "p" }
                    } }
                    tbody {
                        @for (name, c) in cov {
                            tr data-element=(name) {
                                th scope="row" { (name) }
                                td.num { (unc(c.combined)) }
                                td.num { (crate::http::ui::format::dof(Some(c.effective_dof))) }
                                td.num { (crate::http::ui::format::factor(c.coverage_factor)) }
                                td.num { (crate::http::ui::format::percent(c.coverage_probability)) }
                            }
                        }
                    }
                } }
            }
        }
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
                    "RMS residual " (num(f.rms_g)) " g on " (f.degrees_of_freedom) " degrees of freedom; "
                    (f.evaluations) " evaluations (" (f.stop) "); spread of the directions " (num(f.spread))
                    "; S_xy, S_xz and S_yz are zero by the frame convention (the sensor's x axis and "
                    "xy-plane define the frame)"
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
            @let columns: Vec<Notation> = (0..d.residuals.first().map_or(0, Vec::len))
                .map(|k| Notation::of(d.residuals.iter().filter_map(|r| r.get(k).copied())))
                .collect();
            tbody {
                @for (p, r) in d.residuals.iter().enumerate() {
                    tr { th scope="row" { (p + 1) } @for (k, x) in r.iter().enumerate() { td.num { (columns[k].num(*x)) } } }
                }
            }
        } }
        },
    }
}
