//! A single-axis result's tables that its page and its certificate both
//! show: the uncertainty budget, the decision against the sensor type's
//! limits, and as found against the previous calibration.

use maud::{Markup, html};

use super::badge;
use super::format::{given, num, opt, unc};
use super::result::ResultDoc;

/// The uncertainty budget table (also on the certificate).
pub fn budget(d: &ResultDoc) -> Markup {
    html! {
        @if let Some(u) = &d.uncertainty {
            div.table-wrap tabindex="0" role="region" aria-label="Uncertainty budget" {
                table #budget .cards {
                    caption {
                        "Uncertainty budget, each term in its coefficient's unit ("
                        @for (i, (t, _)) in u.terms.iter().enumerate() {
                            @if i > 0 { ", " }
                            (t.name()) " in " (super::format::term_unit(t, &d.unit))
                        }
                        "); expanded" (super::coverage::coverage_statement(u))
                    }
                    thead { tr {
                        th scope="col" { "Term" }
                        th scope="col" .num { "Statistical" }
                        th scope="col" .num { "Indexing" }
                        th scope="col" .num { "Gravity" }
                        th scope="col" .num { "Model" }
                        th scope="col" .num { "Combined" }
                        th scope="col" .num { "ν" sub { "eff" } }
                        th scope="col" .num { "k" }
                        th scope="col" .num { "p" }
                        th scope="col" .num { "Expanded U" }
                    } }
                    tbody {
                        @for (t, b) in u.terms.iter() {
                            @let c = b.covered(u.coverage_factor);
                            tr data-term=(t.name()) {
                                th scope="row" { (t.name()) }
                                td.num data-label="Statistical" { (unc(b.statistical)) }
                                td.num data-label="Indexing" { (unc(b.indexing)) }
                                td.num data-label="Gravity" { (unc(b.gravity)) }
                                td.num data-label="Model" { (unc(b.model)) }
                                td.num data-label="Combined" { (unc(b.combined)) }
                                td.num data-label="νeff" { (super::format::dof(c.effective_dof)) }
                                td.num data-label="k" { (super::format::factor(c.k)) }
                                td.num data-label="p" { (super::format::percent(c.p)) }
                                td.num data-label="Expanded U" { (unc(b.expanded)) }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The decision table (also on the certificate).
pub fn decision(d: &ResultDoc) -> Markup {
    html! {
        @if let Some(dec) = &d.decision {
            p { "Rule " strong { (dec.rule) } " (ILAC-G8); verdict " (badge(&dec.verdict, &dec.verdict)) }
            div.table-wrap tabindex="0" role="region" aria-label="Decision" {
                table #decision .cards {
                    caption { "Each limited coefficient against its limits, in its coefficient's unit (k0 in " (d.unit) ", ki, kp, ko in " (d.unit) "/g)" }
                    thead { tr {
                        th scope="col" { "Term" }
                        th scope="col" .num { "Value" }
                        th scope="col" .num { "Min" }
                        th scope="col" .num { "Max" }
                        th scope="col" .num { "U" }
                        th scope="col" { "Verdict" }
                    } }
                    tbody {
                        @for (t, x) in dec.terms.iter() {
                            tr data-term=(t.name()) {
                                th scope="row" { (t.name()) }
                                td.num data-label="Value" { (num(x.value)) }
                                td.num data-label="Min" { (opt(x.min, given)) }
                                td.num data-label="Max" { (opt(x.max, given)) }
                                td.num data-label="U" { (unc(x.expanded)) }
                                td data-label="Verdict" { (badge(&x.verdict, &x.verdict)) }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The as-found table (also on the certificate).
pub fn as_found(d: &ResultDoc) -> Markup {
    html! {
        @if let Some(a) = &d.as_found {
            p {
                "Against the previous calibration "
                a href={"/ui/calibrations/" (a.previous_calibration_id)} { code { (a.previous_calibration_id) } }
                ": largest error " strong { (unc(a.max_abs_error_g)) " g" } "."
            }
            div.table-wrap tabindex="0" role="region" aria-label="As found" {
                table #as-found .cards {
                    caption { "Error of the previous coefficients at each position" }
                    thead { tr {
                        th scope="col" { "Position" }
                        th scope="col" .num { "Error (" (d.unit) ")" }
                        th scope="col" .num { "Error (g)" }
                    } }
                    tbody {
                        @for (i, e) in a.positions.iter().enumerate() {
                            tr data-position=(i) {
                                th scope="row" { (d.positions.get(i).map_or_else(|| format!("#{}", i + 1), |p| p.name(i))) }
                                td.num data-label={"Error (" (d.unit) ")"} { (unc(e.error_output)) }
                                td.num data-label="Error (g)" { (unc(e.error_g)) }
                            }
                        }
                    }
                }
            }
        }
    }
}
