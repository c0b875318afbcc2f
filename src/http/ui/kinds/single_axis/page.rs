//! A single axis's calibration on its page (`GET /ui/calibrations/{id}`):
//! the paper's tables (per run; mean and fused with eq. 8 dispersion and
//! standard errors, as its Table 2), residuals per run and position (chart
//! and table), the uncertainty budget, the decision, as found, temperature
//! and quality flags when present.
//!
//! Bounded at any submission the limits allow (1 000 runs, 360 positions):
//! the per-run table shows the first [`RUNS_SHOWN`] runs, and the residual
//! chart and table the first runs that keep them within [`RESIDUALS_SHOWN`]
//! values (at least one run, at most [`RUNS_SHOWN`]); each says what it left
//! out, and the result document (`/v1/calibrations/{id}`) has everything.

use maud::{Markup, html};

use crate::http::ui::axis::{as_found, budget, decision};
use crate::http::ui::badge;
use crate::http::ui::document::Page;
use crate::http::ui::format::{Notation, num, opt, unc};
use crate::http::ui::plot::{self, Chart, Point, Series, XAxis};
use crate::http::ui::result::{LackOfFitDoc, MethodDoc, ResultDoc, WarningDoc};
use crate::http::ui::stored::when;

/// Calibration `d` as its page shows it.
pub fn page(d: &ResultDoc) -> Page<'_> {
    Page {
        id: d.id,
        sensor_id: &d.sensor_id,
        title: "Calibration",
        noun: "calibration",
        verdict: Some(
            html! { @if let Some(dec) = &d.decision { (badge(&dec.verdict, &dec.verdict)) } },
        ),
        supersedes: d.supersedes.as_ref(),
        performed_at: &d.performed_at,
        station_id: d.station_id.as_deref(),
        received_at: &d.received_at,
        facts: html! {
            @if let Some(at) = &d.item_received_at {
                div { dt { "Item received" } dd { (when(at)) } }
            }
            @if let Some(c) = &d.item_condition {
                div { dt { "Condition on receipt" } dd { (c) } }
            }
            div { dt { "Model" } dd { (d.model.join(", ")) " · " (d.mount) " mount" } }
            div { dt { "Runs, batches" } dd { (d.runs.len()) ", " (d.batches) } }
            div { dt { "Unit" } dd { (d.unit) } }
            div { dt { "Sensor type" } dd { (d.sensor_type.as_deref().unwrap_or("none")) } }
            div { dt { "Due" } dd { (d.due_at.as_deref().map_or("—".into(), when)) } }
            div { dt { "Computed by" } dd { (MethodDoc::describe(d.method.as_ref())) } }
            @if let Some(s) = &d.stand {
                div { dt { "Stand" } dd { (s.id.as_deref().unwrap_or("unnamed")) ": " (s.angle_std_arcsec) "″ indexing, " (s.gravity_rel_std) " in g" } }
            }
            @for u in &d.standards {
                div { dt { "Standard (" (u.role) ")" } dd {
                    (u.standard_id) ", " (u.description)
                    @if let Some(serial) = &u.serial { " (serial " (serial) ")" }
                    ": certificate " (u.certificate.number) " of " (u.certificate.issued_by)
                    ", calibrated " (when(&u.certificate.calibrated_at.to_string()))
                    ", due " (when(&u.due_at.to_string()))
                } }
            }
        },
        certified: true,
        downloads: None,
        sections: html! {
            @if let Some(n) = &d.notes { p { "Notes: " (n) } }
            (warnings(d))
            @if d.decision.is_some() {
                h2 { "Decision" }
                (decision(d))
            }
            h2 { "Coefficients" }
            (runs_table(d))
            @if d.uncertainty.is_some() {
                h2 { "Uncertainty" }
                (budget(d))
            }
            @if d.as_found.is_some() {
                h2 { "As found" }
                (as_found(d))
            }
            (temperature(d))
            h2 { "Residuals" }
            (residuals(d))
        },
    }
}

/// Runs listed in the per-run table.
pub const RUNS_SHOWN: usize = 24;

/// Residuals drawn and tabulated at most (runs × positions).
pub const RESIDUALS_SHOWN: usize = 2_000;

/// How many runs the residual chart and table show.
fn residual_runs(d: &ResultDoc) -> usize {
    (RESIDUALS_SHOWN / d.positions.len().max(1)).clamp(1, RUNS_SHOWN)
}

/// A note of what a table leaves out of `total` runs, showing `shown`.
fn left_out(shown: usize, total: usize, id: &str) -> Markup {
    html! {
        @if total > shown {
            p.notice.left-out {
                "Runs " (shown + 1) "–" (total) " are not shown here; the "
                a href={"/v1/calibrations/" (id)} { "result document" }
                " has every run."
            }
        }
    }
}

fn terms(d: &ResultDoc) -> Vec<accelcal_core::Term> {
    d.fused.coefficients.iter().map(|(t, _)| t).collect()
}

fn runs_table(d: &ResultDoc) -> Markup {
    let terms = terms(d);
    let v = |m: &accelcal_core::TermMap<f64>, t| m.get(t).copied();
    // A single run has no eq. 8: its rows show dashes.
    let none = accelcal_core::TermMap(Vec::new());
    let mean_dispersion = d.mean.dispersion.as_ref().unwrap_or(&none);
    let fused_dispersion = d.fused.dispersion.as_ref().unwrap_or(&none);
    // One notation per column: a term's coefficients (runs, mean, fused)
    // and its spreads (dispersions, standard error) alike, decided by every
    // number the column shows.
    let maps = [
        &d.mean.coefficients,
        &d.fused.coefficients,
        mean_dispersion,
        &d.fused.std_errors,
        fused_dispersion,
    ];
    let notation: Vec<(accelcal_core::Term, Notation)> = terms
        .iter()
        .map(|&t| {
            let shown = d.runs.iter().take(RUNS_SHOWN);
            let column = shown
                .filter_map(|r| v(&r.coefficients, t))
                .chain(maps.iter().filter_map(|m| v(m, t)));
            (t, Notation::of(column))
        })
        .collect();
    let col = |t: &accelcal_core::Term| {
        notation
            .iter()
            .find(|(u, _)| u == t)
            .map_or(Notation::Scientific, |(_, n)| *n)
    };
    let spread = col;
    let rms = Notation::of(d.runs.iter().take(RUNS_SHOWN).map(|r| r.residual_rms));
    html! {
        div.table-wrap tabindex="0" role="region" aria-label="Coefficients per run, mean and fused" {
            table #estimates .cards {
                caption { "Per run and fused (as the paper's Table 2); k0 in " (d.unit) ", the others in " (d.unit) " per g to their degree (ki, kp, ko in " (d.unit) "/g)" }
                thead { tr {
                    th scope="col" { "" }
                    @for t in &terms { th scope="col" .num { (t.name()) } }
                    th scope="col" .num { "Residual RMS" }
                    th scope="col" .num { "dof" }
                    @if d.temperatures_c.is_some() { th scope="col" .num { "°C" } }
                } }
                tbody {
                    @for (j, r) in d.runs.iter().enumerate().take(RUNS_SHOWN) {
                        tr data-run=(j) {
                            th scope="row" { "Run " (j + 1) }
                            @for t in &terms { td.num data-label=(t.name()) { (v(&r.coefficients, *t).map_or("—".into(), |x| col(t).num(x))) } }
                            td.num data-label="Residual RMS" { (rms.unc(r.residual_rms)) }
                            td.num data-label="dof" { (r.dof) }
                            @if let Some(temps) = &d.temperatures_c { td.num data-label="°C" { (opt(temps.get(j).copied(), |x| format!("{x}"))) } }
                        }
                    }
                    tr.summary data-row="mean" {
                        th scope="row" { "Mean (eq. 1)" }
                        @for t in &terms { td.num data-label=(t.name()) { (v(&d.mean.coefficients, *t).map_or("—".into(), |x| col(t).num(x))) } }
                        td {} td {} @if d.temperatures_c.is_some() { td {} }
                    }
                    tr data-row="mean-dispersion" {
                        th scope="row" { "Dispersion about the mean (eq. 8)" }
                        @for t in &terms { td.num data-label=(t.name()) { (v(mean_dispersion, *t).map_or("—".into(), |x| spread(t).unc(x))) } }
                        td {} td {} @if d.temperatures_c.is_some() { td {} }
                    }
                    tr.summary data-row="fused" {
                        th scope="row" { "Fused (batch estimate)" }
                        @for t in &terms { td.num data-label=(t.name()) { (v(&d.fused.coefficients, *t).map_or("—".into(), |x| col(t).num(x))) } }
                        td {} td {} @if d.temperatures_c.is_some() { td {} }
                    }
                    tr data-row="fused-std-error" {
                        th scope="row" { "Fused standard error" }
                        @for t in &terms { td.num data-label=(t.name()) { (v(&d.fused.std_errors, *t).map_or("—".into(), |x| spread(t).unc(x))) } }
                        td {} td {} @if d.temperatures_c.is_some() { td {} }
                    }
                    tr data-row="fused-dispersion" {
                        th scope="row" { "Dispersion about the fused value (eq. 8)" }
                        @for t in &terms { td.num data-label=(t.name()) { (v(fused_dispersion, *t).map_or("—".into(), |x| spread(t).unc(x))) } }
                        td {} td {} @if d.temperatures_c.is_some() { td {} }
                    }
                }
            }
        }
        (left_out(RUNS_SHOWN.min(d.runs.len()), d.runs.len(), &d.id.to_string()))
        p.muted {
            @if let Some(note) = &d.fused.note {
                "Not fused: " (note) "."
            } @else {
                "Batches: "
                @for (k, b) in d.fused.batches.iter().enumerate() {
                    @if k > 0 { "; " }
                    "runs " (b.runs.iter().map(|r| (r + 1).to_string()).collect::<Vec<_>>().join(", "))
                }
                "."
            }
            " Condition number of the design " (format!("{:.4}", d.condition_number)) "."
        }
    }
}

fn residuals(d: &ResultDoc) -> Markup {
    let names: Vec<String> = d
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| p.name(i))
        .collect();
    let shown = residual_runs(d);
    let chart = Chart {
        id: "residuals".into(),
        title: "Residuals of each run at each position".into(),
        y_label: format!("residual ({})", d.unit),
        x: XAxis::Index(names.clone()),
        series: d
            .runs
            .iter()
            .take(shown)
            .enumerate()
            .map(|(j, r)| Series {
                name: format!("run {}", j + 1),
                points: r
                    .residuals
                    .iter()
                    .enumerate()
                    .map(|(i, e)| Point {
                        x: i as f64,
                        y: *e,
                        err: None,
                        data: vec![("run", j.to_string()), ("position", i.to_string())],
                        label: format!("run {}, {}: {}", j + 1, names[i], unc(*e)),
                        flagged: false,
                    })
                    .collect(),
            })
            .collect(),
        rules: vec![],
        segments: vec![],
    };
    html! {
        section.chart-block.stacked aria-label="Residuals" {
            (plot::render(&chart))
            div.table-wrap tabindex="0" role="region" aria-label="Residuals per run and position" {
                table #residuals-table .cards {
                    caption { "Residual of each run at each position (" (d.unit) ")" }
                    thead { tr {
                        th scope="col" { "Position" }
                        @for j in 0..shown.min(d.runs.len()) { th scope="col" .num { "Run " (j + 1) } }
                    } }
                    tbody {
                        @for (i, name) in names.iter().enumerate() {
                            tr data-position=(i) {
                                th scope="row" { (name) }
                                @for (j, r) in d.runs.iter().take(shown).enumerate() { td.num data-label={"Run " (j + 1)} { (opt(r.residuals.get(i).copied(), unc)) } }
                            }
                        }
                    }
                }
            }
            (left_out(shown.min(d.runs.len()), d.runs.len(), &d.id.to_string()))
        }
    }
}

fn temperature(d: &ResultDoc) -> Markup {
    html! {
        @if let Some(t) = &d.temperature {
            h2 { "Temperature" }
            div.table-wrap tabindex="0" role="region" aria-label="Temperature sensitivity" {
                table #temperature .cards {
                    caption { "Per-run coefficients against run temperature (least squares)" }
                    thead { tr {
                        th scope="col" { "Term" }
                        th scope="col" .num { "Per kelvin" }
                        th scope="col" .num { "SE" }
                        th scope="col" .num { "Reference °C" }
                        th scope="col" .num { "Value there" }
                    } }
                    tbody {
                        @for (term, s) in t.iter() {
                            tr data-term=(term.name()) {
                                th scope="row" { (term.name()) }
                                td.num data-label="Per kelvin" { (unc(s.per_kelvin)) }
                                td.num data-label="SE" { (opt(s.std_error, unc)) }
                                td.num data-label="Reference °C" { (format!("{:.2}", s.reference_c)) }
                                td.num data-label="Value there" { (num(s.value_at_reference)) }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// An F statistic at a readable precision.
fn stat(f: f64) -> String {
    if f >= 1e4 {
        format!("{f:.3e}")
    } else {
        format!("{f:.3}")
    }
}

/// A p-value at a readable precision.
fn p_value(p: f64) -> String {
    if p < 1e-3 {
        format!("{p:.2e}")
    } else {
        format!("{p:.3}")
    }
}

fn warnings(d: &ResultDoc) -> Markup {
    let list = d
        .quality
        .as_ref()
        .map_or(&[][..], |q| q.warnings.as_slice());
    // Implausibly consistent batches, one notice for all of them.
    let consistent: Vec<String> = list
        .iter()
        .filter_map(|w| match w {
            WarningDoc::ImplausiblyConsistentBatch {
                batch,
                term,
                std,
                floor,
            } => Some(format!(
                "batch {} on {term} ({} against a floor of {})",
                batch + 1,
                unc(*std),
                unc(*floor)
            )),
            _ => None,
        })
        .collect();
    let misfit = list
        .iter()
        .any(|w| matches!(w, WarningDoc::LackOfFit { .. }));
    html! {
        @for w in list.iter().filter(|w| !matches!(w, WarningDoc::ImplausiblyConsistentBatch { .. })) {
            p.notice.warning role="note" {
                @match w {
                    WarningDoc::IllConditioned { condition_number, terms } => {
                        strong { "Ill-conditioned design. " }
                        "Condition number " (format!("{condition_number:.3e}")) ": the positions barely separate "
                        (terms.join(", ")) "."
                    }
                    WarningDoc::LackOfFit { f, df1, df2, p_value, pure_error_std, lack_of_fit_std } => {
                        strong { "Lack of fit. " }
                        "The residuals (" (unc(*lack_of_fit_std)) " per sample) exceed the scatter of repeated samples ("
                        (unc(*pure_error_std)) "): F = " (stat(*f)) " on (" (df1) ", " (df2) "), p = "
                        (self::p_value(*p_value)) ". The model misses something the same in every run; the "
                        "budget's model component carries it."
                    }
                    WarningDoc::NoisyRun { run, f, p_value, residual_std, others_residual_std, pure_error_std, others_pure_error_std, residual_rms, median_residual_rms, .. } => {
                        strong { "Noisy run. " }
                        @match (f, p_value, pure_error_std.zip(*others_pure_error_std), residual_std.zip(*others_residual_std)) {
                            (Some(f), Some(p), Some((s, o)), _) => {
                                "Run " (run + 1) "'s repeated samples scatter by " (unc(s)) " against " (unc(o))
                                " in the other runs: F = " (stat(*f)) ", p = " (self::p_value(*p)) "."
                            }
                            (Some(f), Some(p), None, Some((s, o))) => {
                                "Run " (run + 1) " fits with residual deviation " (unc(s)) " against " (unc(o))
                                " for the other runs: F = " (stat(*f)) ", p = " (self::p_value(*p)) "."
                            }
                            _ => {
                                "Run " (run + 1) " fits with residual RMS " (opt(*residual_rms, unc))
                                ", more than three times the median " (opt(*median_residual_rms, unc)) "."
                            }
                        }
                    }
                    WarningDoc::ImplausiblyConsistentBatch { .. } => {}
                    WarningDoc::UnmodelledTerm { term, f, p_value } => {
                        strong { "Unmodelled term. " }
                        "Adding " code { (term) } " to the model would explain the data significantly better: F = "
                        (stat(*f)) ", p = " (self::p_value(*p_value)) "."
                    }
                }
            }
        }
        @if !consistent.is_empty() {
            p.notice.warning role="note" {
                strong { "Implausibly consistent batches. " }
                "These agree better than a hundredth of their runs' own standard errors, and were weighted "
                "at that floor: " (consistent.join("; ")) "."
                @if misfit { " With lack of fit, the runs' standard errors carry the misfit as well." }
            }
        }
        @if let Some(lof) = d.quality.as_ref().and_then(|q| q.lack_of_fit.as_ref()) {
            p.muted #lack-of-fit {
                @match lof {
                    LackOfFitDoc::Tested { f, df1, df2, p_value, alpha } => {
                        "Lack-of-fit test: F = " (stat(*f)) " on (" (df1) ", " (df2) "), p = "
                        (self::p_value(*p_value)) @if p_value >= alpha { ", no lack of fit at " (alpha) "." } @else { "." }
                    }
                    LackOfFitDoc::NotTested { reason } => {
                        "Lack of fit not tested: " (match reason.as_str() {
                            "no_residual_dof" => "as many positions as terms, every run fits exactly.",
                            "no_replicates" => "no position holds two samples, so there is no pure error to compare with.",
                            _ => "the repeated samples are identical.",
                        })
                    }
                }
            }
        }
    }
}
