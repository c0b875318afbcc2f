//! The printable calibration certificate (HTML, A4 under `@media print`) of
//! a single-axis calibration, and what every certificate shares (its
//! [`Context`], frame and sections): answered by
//! `GET /v1/calibrations/{id}/certificate` with a bearer token, and
//! `GET /ui/calibrations/{id}/certificate` from the pages ([`super::issue`]).
//!
//! It states what a lab signs (ISO/IEC 17025 §7.8 where accelcal knows it):
//! the customer and the item (manufacturer, model, serial, sensor, type), where and how it was calibrated (station, stand,
//! reference standards, method, model), when, the environmental conditions,
//! the fused coefficients rounded to their expanded uncertainty (GUM 7.2.6)
//! with units, the coverage factor and its probability, the decision rule
//! and verdict, as found, the due date (only when no customer is recorded or
//! the customer agreed to one), the metrological traceability from
//! the standards' statements — and what makes it verifiable: the SHA-256 of
//! the stored submission, the accelcal version and the certificate's own
//! URL. Printed, every page carries the title and number (a table header
//! Chromium repeats) and "Page n of N" (the stylesheet's `@page
//! certificate`), and the last ends with an end marker. The document carries its stylesheet inline
//! (allowed by hash in its Content-Security-Policy), so a saved copy prints
//! the same.

use std::sync::LazyLock;

use axum::http::{HeaderMap, header};
use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;
use maud::{DOCTYPE, Markup, PreEscaped, html};
use sha2::{Digest, Sha256};

use super::assets::STYLESHEET;
use super::axis::{as_found, budget, decision};
use super::coverage::coverage_statement;
use super::format::{dof, factor, num, percent, term_unit, unc, value_and_uncertainty};
use super::result::{MethodDoc, ResultDoc};
use super::stored::when;
use super::{badge, review};
use crate::domain::timestamp::Timestamp;
use crate::http::problem::Problem;
use crate::http::{AppState, path_id};

/// The certificate's Content-Security-Policy: its own inline stylesheet
/// (by hash), the laboratory's logo embedded as a `data:` image, and
/// nothing else.
pub static CSP: LazyLock<String> = LazyLock::new(|| {
    let hash = STANDARD.encode(Sha256::digest(STYLESHEET.as_bytes()));
    format!(
        "default-src 'none'; style-src 'sha256-{hash}'; img-src data:; frame-ancestors 'none'; \
         base-uri 'none'; form-action 'none'"
    )
});

/// The paper the method follows.
pub const PAPER: &str = "Pei Fang-xia, Wang Heng-hui, \u{201c}Identification of Stationary Model \
     for Accelerometer Based on Data Fusion\u{201d}, Chinese Journal of Electron Devices 28(4), 2005";

/// Everything a certificate shows beyond the result document.
pub struct Context {
    /// SHA-256 of the stored submission, hex.
    pub submission_sha256: String,
    /// Its media type.
    pub content_type: String,
    /// The certificate's own URL.
    pub url: String,
    /// When this copy was produced.
    pub issued: Timestamp,
    /// The laboratory that issues it.
    pub laboratory: crate::http::Laboratory,
    /// The calibration's state.
    pub state: crate::domain::review::State,
    /// Its signatures, in order.
    pub signatures: Vec<crate::domain::review::Signature>,
    /// The item behind the sensor id, when recorded.
    pub item: Option<crate::domain::customers::Item>,
    /// The item's customer, when recorded.
    pub customer: Option<crate::domain::customers::Customer>,
    /// When this is an amendment: which, and why.
    pub amendment: Option<Amendment>,
}

/// An amendment of an issued certificate: revision `number + 1` of the
/// same certificate number.
#[derive(Clone, Debug, PartialEq)]
pub struct Amendment {
    /// 1 for the first amendment (revision 2).
    pub number: u32,
    /// Why it was amended.
    pub reason: String,
}

impl Context {
    /// The certificate's identifier: the calibration id, and for an
    /// amendment `-A` and its number (`…-A1`).
    pub fn identifier(&self, id: &uuid::Uuid) -> String {
        match &self.amendment {
            Some(a) => format!("{id}-A{}", a.number),
            None => id.to_string(),
        }
    }

    /// The identifier of the revision this one amends.
    pub fn amends(&self, id: &uuid::Uuid) -> Option<String> {
        self.amendment.as_ref().map(|a| match a.number {
            1 => id.to_string(),
            n => format!("{id}-A{}", n - 1),
        })
    }
}

/// The certificate document.
pub fn render(d: &ResultDoc, c: &Context) -> Markup {
    let statement = d.uncertainty.as_ref().map(coverage_statement);
    let body = html! {
                    h2 { "Item and calibration" }
                    dl.facts {
                        (customer_and_item(c))
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
                    }
                    h2 { "Environmental conditions" }
                    dl.facts {
                        div { dt { "Temperature" } dd { (temperatures(d)) } }
                        div { dt { "Local gravity" } dd { (local_gravity(d)) } }
                    }
                    (standards(&d.standards))
                    h2 { "Method" }
                    p {
                        "Tumble test in the 1 g field on a dividing head (" (d.mount) " mount, "
                        (d.positions.len()) " positions, " (d.runs.len()) " runs). The static model "
                        code { "U = Σ k·f(a)" } " with terms " strong { (d.model.join(", ")) }
                        " is identified from each run by least squares; the runs are fused by batch "
                        "estimation (" (d.batches) " batches, inverse-variance weighting of batch means), after "
                        (PAPER) ". Uncertainty after the GUM: the fused standard error, the stand's indexing "
                        "error, the uncertainty of gravity and, when the lack-of-fit test finds the model short of the data, "
                        "the model's own standard error, combined in quadrature and expanded"
                        @if let Some(s) = &statement { (s) } "."
                    }
                    h2 { "Results" }
                    div.table-wrap tabindex="0" role="region" aria-label="Fused coefficients" {
                        table #certificate-results {
                            caption {
                                "Fused coefficients, each rounded to its expanded uncertainty's second significant digit, "
                                "with its combined standard uncertainty u"
                                sub { "c" } ", effective degrees of freedom ν"
                                sub { "eff" } ", coverage factor k and coverage probability p"
                            }
                            thead { tr {
                                th scope="col" { "Term" }
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
                                @for (t, v) in d.fused.coefficients.iter() {
                                    @let covered = d.uncertainty.as_ref().and_then(|u| u.covered(t));
                                    @let expanded = d.uncertainty.as_ref().and_then(|u| u.terms.get(t)).map(|b| b.expanded);
                                    @let (value, u) = match expanded {
                                        Some(u) => { let (v, u) = value_and_uncertainty(*v, u); (v, Some(u)) }
                                        None => (num(*v), None),
                                    };
                                    tr data-term=(t.name()) {
                                        th scope="row" { (t.name()) }
                                        td.num { (value) }
                                        td.num { (d.fused.std_errors.get(t).map_or("—".into(), |x| unc(*x))) }
                                        td.num { (covered.map_or("—".into(), |c| unc(c.combined))) }
                                        td.num { (covered.map_or("—".into(), |c| dof(c.effective_dof))) }
                                        td.num { (covered.map_or("—".into(), |c| factor(c.k))) }
                                        td.num { (covered.map_or("—".into(), |c| percent(c.p))) }
                                        td.num { (u.unwrap_or_else(|| "—".into())) }
                                        td { (term_unit(t, &d.unit)) }
                                    }
                                }
                            }
                        }
                    }
                    (budget(d))
                    @if d.decision.is_some() {
                        h2 { "Conformity" }
                        (decision(d))
                    }
                    @if d.as_found.is_some() {
                        h2 { "As found" }
                        (as_found(d))
                    }
                    (traceability(&d.standards))
                    (verification(c, Some(MethodDoc::describe(d.method.as_ref()))))
    };
    frame(
        &Frame {
            id: &d.id,
            running: &d.sensor_id,
            supersedes: d.supersedes.as_ref(),
            verdict: d.decision.as_ref().map(|dec| dec.verdict.as_str()),
        },
        c,
        body,
    )
}

/// What every certificate says of its own scope (ISO/IEC 17025
/// §7.8.2.1 b, as the Digital Calibration Certificate's statements do).
pub const SCOPE: &str = "The results relate only to the item calibrated, as received, at the time \
    and in the conditions of the calibration stated in this certificate. This certificate may \
    not be reproduced other than in full without the laboratory's written approval.";

/// What a printed certificate's frame shows of its calibration.
pub struct Frame<'a> {
    /// The calibration (the certificate's number).
    pub id: &'a uuid::Uuid,
    /// After the number in the running header: the sensor (and its kind).
    pub running: &'a str,
    /// The calibration it supersedes.
    pub supersedes: Option<&'a crate::domain::review::Supersedes>,
    /// The verdict, when judged.
    pub verdict: Option<&'a str>,
}

/// A printed certificate around its `body`: the document with the inline
/// stylesheet, the running header repeated on every printed page (the
/// number, and the review notice of a withdrawn or superseded one; the
/// page numbers are the stylesheet's, `@page certificate`), the head (logo,
/// number, the certificate it replaces, the laboratory; verdict and state)
/// and the end line. The single-axis and the triad certificate alike.
pub fn frame(f: &Frame<'_>, c: &Context, body: Markup) -> Markup {
    let notice = review::notice(c.state, &c.signatures);
    let id = f.id;
    html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                meta name="viewport" content="width=device-width, initial-scale=1";
                title { "Calibration certificate " (id) }
                style { (PreEscaped(STYLESHEET)) }
            }
            body.certificate {
                main {
                    table.cert-pages role="presentation" {
                    thead { tr { td {
                        div.cert-running { "Calibration certificate No. " (id) " · " (f.running) }
                        @if let Some(n) = &notice {
                            div.cert-withdrawn role="status" { (n) }
                        }
                    } } }
                    tbody { tr { td {
                    div.cert-head {
                        div {
                            @if let Some(logo) = &c.laboratory.logo {
                                img.cert-logo src=(logo) alt="Laboratory logo";
                            }
                            h1 { "Calibration certificate" }
                            p.muted { "No. " code { (id) } }
                            @if let Some(a) = &c.amendment {
                                p.cert-replaces {
                                    "Amendment " (a.number) " to certificate No. " code { (id) }
                                    " (revision " (a.number + 1) "), which it replaces. Reason: " (a.reason)
                                }
                            }
                            @if let Some(s) = f.supersedes {
                                (replaces(s))
                            }
                            (laboratory(&c.laboratory))
                        }
                        div {
                            @if let Some(v) = f.verdict {
                                p { "Verdict " (badge(v, v)) }
                            }
                            p { "State " (review::state_badge(c.state)) }
                        }
                    }
                    (body)
                    p.cert-scope { (SCOPE) }
                    p.cert-end { "End of certificate No. " (id) }
                    } } }
                    }
                }
            }
        }
    }
}

/// The reference standards used, with their certificates and
/// traceability (nothing when none was named).
pub fn standards(standards: &[crate::domain::standards::UsedStandard]) -> Markup {
    html! {
        @if !standards.is_empty() {
            h2 { "Reference standards" }
            div.table-wrap tabindex="0" role="region" aria-label="Reference standards" {
                table #certificate-standards {
                    thead { tr {
                        th scope="col" { "Role" } th scope="col" { "Standard" } th scope="col" { "Certificate" }
                        th scope="col" { "Calibrated" } th scope="col" { "Due" } th scope="col" { "Traceability" }
                    } }
                    tbody {
                        @for u in standards {
                            tr {
                                td { (u.role) }
                                td { (u.standard_id) ", " (u.description) @if let Some(serial) = &u.serial { " (serial " (serial) ")" } }
                                td { (u.certificate.number) ", " (u.certificate.issued_by) }
                                td { (when(&u.certificate.calibrated_at.to_string())) }
                                td { (when(&u.due_at.to_string())) }
                                td { (u.parameters.traceability) }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The customer and the item, as the certificate's facts list them.
pub fn customer_and_item(c: &Context) -> Markup {
    html! {
                        div { dt { "Customer" } dd { @match &c.customer {
                            Some(cu) => { (cu.name) @if let Some(a) = &cu.address { ", " (a) } },
                            None => "not recorded",
                        } } }
                        div { dt { "Item" } dd { (c.item.as_ref().map_or("not described".into(), |i| i.describe())) } }
    }
}

/// The traceability statement: through the standards used, or that none
/// establishes it.
pub fn traceability(standards: &[crate::domain::standards::UsedStandard]) -> Markup {
    html! {
                    h2 { "Metrological traceability" }
                    @if standards.is_empty() {
                        p { "No reference standard was named with this calibration: this certificate does not establish the metrological traceability of its results." }
                    } @else {
                        p { "The results are traceable to the SI through the reference standards listed above, each in calibration when the test was performed:" }
                        ul {
                            @for u in standards {
                                li { strong { (u.standard_id) } " (certificate " (u.certificate.number) "): " (u.parameters.traceability) }
                            }
                        }
                    }
    }
}

/// What makes the document verifiable (the submission's digest, what
/// computed and rendered it, when, its own URL), then the review and its
/// signatures.
pub fn verification(c: &Context, computed_by: Option<String>) -> Markup {
    html! {
                    h2 { "Verification of this document" }
                    dl.facts {
                        div { dt { "Submission SHA-256" } dd.sha { (c.submission_sha256) } }
                        div { dt { "Submission format" } dd { (c.content_type) } }
                        @if let Some(by) = computed_by { div { dt { "Computed by" } dd { (by) } } }
                        div { dt { "Rendered by" } dd { "accelcal " (env!("CARGO_PKG_VERSION")) } }
                        div { dt { "Issued" } dd { (super::format::instant(&c.issued)) } }
                        div { dt { "This certificate" } dd.sha { (c.url) } }
                    }
                    h2 { "Review and signatures" }
                    @if c.signatures.is_empty() {
                        p { "Not reviewed: this certificate carries no approval. A reviewer approves it in accelcal, and a copy issued afterwards shows the signature here." }
                    } @else {
                        (review::signatures_table(&c.signatures))
                    }
    }
}

/// Who issues the certificate: the laboratory's name, address and
/// accreditation as configured, or that none is.
pub fn laboratory(lab: &crate::http::Laboratory) -> Markup {
    html! {
        div.cert-lab {
            @match &lab.name {
                Some(name) => { p { strong { (name) } } },
                None => { p.muted { "Laboratory not configured (--lab-name, --lab-address, --lab-accreditation)" } },
            }
            @if let Some(address) = &lab.address { p { (address) } }
            @if let Some(accreditation) = &lab.accreditation { p { "Accredited: " (accreditation) } }
        }
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

/// The statement that a certificate replaces the superseded one's.
pub fn replaces(s: &crate::domain::review::Supersedes) -> Markup {
    html! {
        p.cert-replaces { "This certificate replaces certificate No. " code { (s.calibration_id) } ", which is superseded and no longer to be used. Reason: " (s.reason) }
    }
}

/// The certificate's own URL: under `--public-url`, else the request's host.
fn own_url(state: &AppState, headers: &HeaderMap, id: &uuid::Uuid) -> String {
    let path = format!("/v1/calibrations/{id}/certificate");
    match &state.web.public_url {
        Some(base) => format!("{}{path}", base.trim_end_matches('/')),
        None => match headers.get(header::HOST).and_then(|h| h.to_str().ok()) {
            Some(host)
                if host
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || ".-:[]".contains(c)) =>
            {
                format!("http://{host}{path}")
            }
            _ => path,
        },
    }
}

/// The [`Context`] of calibration `raw_id` of sensor `sensor_id`: the
/// stored submission's digest, the review, the item and its customer.
pub async fn context(
    state: &AppState,
    headers: &HeaderMap,
    raw_id: &str,
    sensor_id: &str,
) -> Result<Context, Problem> {
    let id = path_id(raw_id, "calibration")?;
    let s = state
        .store
        .submission(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    let (state_now, signatures) = super::stored::record(state, raw_id).await?;
    let item = state.store.item(sensor_id.to_owned()).await?;
    let customer = match item.as_ref().and_then(|i| i.customer.clone()) {
        Some(id) => state.store.customer(id).await?,
        None => None,
    };
    Ok(Context {
        item,
        customer,
        state: state_now,
        signatures,
        submission_sha256: hex::encode(Sha256::digest(&s.body)),
        content_type: s.content_type,
        url: own_url(state, headers, &id),
        issued: Timestamp::now(),
        laboratory: state.web.laboratory.clone(),
        amendment: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_policy_allows_exactly_the_inline_stylesheet() {
        let hash = STANDARD.encode(Sha256::digest(STYLESHEET.as_bytes()));
        assert!(CSP.contains(&format!("'sha256-{hash}'")));
        assert!(!CSP.contains("unsafe-inline"));
        assert!(CSP.starts_with("default-src 'none'"));
    }
}
