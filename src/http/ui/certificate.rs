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
use super::document::{Column, Document, Quantity};
use super::format::{dof, factor, num, percent, unc, value_and_uncertainty};
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
    /// The DCC issued with it, when one is: what the printed certificate
    /// says of it.
    pub dcc: Option<DccFile>,
}

/// What the printed certificate says of the DCC issued with it: the file's
/// SHA-256 (hex), so that a reader of the PDF can match it to the XML, and
/// who signed it (none: issued unsigned).
#[derive(Clone, Debug, PartialEq)]
pub struct DccFile {
    /// SHA-256 of the DCC's bytes, hex.
    pub sha256: String,
    /// The signing certificate's subject and SHA-256, when signed.
    pub signed_by: Option<(String, String)>,
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

/// The printed certificate of a calibration of any kind: the frame, the
/// item and the calibration, the kind's method, its quantities (each
/// rounded to its expanded uncertainty, GUM 7.2.6, with `u_c`, `ν_eff`,
/// `k`, `p` and its unit), the kind's sections beside them, the
/// traceability and what makes it verifiable.
pub fn render(doc: &Document<'_>, c: &Context) -> Markup {
    let p = &doc.printed;
    let body = html! {
                    h2 { "Item and calibration" }
                    dl.facts {
                        (customer_and_item(c))
                        (p.facts)
                    }
                    (p.before_method)
                    h2 { "Method" }
                    p { (p.method) }
                    h2 { "Results" }
                    div.table-wrap tabindex="0" role="region" aria-label=(p.label) {
                        table #certificate-results {
                            caption { (p.caption) }
                            thead { tr {
                                th scope="col" { @match p.column { Column::Term => "Term", Column::Element => "Element" } }
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
                                @for q in &doc.quantities {
                                    @match p.column {
                                        Column::Term => { tr data-term=(q.name) { (cells(q)) } },
                                        Column::Element => { tr data-element=(q.name) { (cells(q)) } },
                                    }
                                }
                            }
                        }
                    }
                    (p.after_results)
                    @if let Some(m) = &p.conformity {
                        h2 { "Conformity" }
                        (m)
                    }
                    @if let Some(m) = &p.as_found {
                        h2 { "As found" }
                        (m)
                    }
                    (p.before_traceability)
                    (traceability(doc.admin.standards))
                    (verification(c, p.computed_by.clone()))
    };
    frame(
        &Frame {
            id: &doc.admin.id,
            running: &doc.running,
            supersedes: doc.admin.supersedes,
            verdict: doc.admin.judged.as_ref().map(|j| j.verdict),
        },
        c,
        body,
    )
}

/// One quantity's cells in the results: name, value, standard error,
/// `u_c`, `ν_eff`, `k`, `p`, `U`, unit — the value rounded to `U` where
/// one is stated; a fixed quantity as zero, with why.
fn cells(q: &Quantity) -> Markup {
    let (value, expanded) = match q.expanded {
        Some(u) => value_and_uncertainty(q.value, u),
        None => (num(q.value), "—".into()),
    };
    let stated = q.covered.filter(|_| q.expanded.is_some());
    html! {
        th scope="row" { (q.name) }
        @if let Some(why) = q.fixed {
            td.num { "0" } td.num { "—" } td.num { "—" } td.num { "—" } td.num { "—" } td.num { "—" } td.num { "—" }
            td { (why) }
        } @else {
            td.num { (value) }
            td.num { (q.std_error.map_or("—".into(), unc)) }
            td.num { (q.combined().map_or("—".into(), unc)) }
            td.num { (q.covered.map_or("—".into(), |c| dof(c.effective_dof))) }
            td.num { (stated.map_or("—".into(), |c| factor(c.k))) }
            td.num { (stated.map_or("—".into(), |c| percent(c.p))) }
            td.num { (expanded) }
            td { (q.unit) }
        }
    }
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
                        @if let Some(f) = &c.dcc {
                            div { dt { "Digital Calibration Certificate (XML) SHA-256" } dd.sha #dcc-sha256 { (f.sha256) } }
                            div { dt { "DCC signature" } dd #dcc-signature {
                                @match &f.signed_by {
                                    Some((subject, fingerprint)) => {
                                        "Signed (XML Signature, XAdES) by " (subject) "; signing certificate SHA-256 "
                                        span.sha { (fingerprint) }
                                    },
                                    None => { "Unsigned: the laboratory issued this DCC without a digital signature; only its SHA-256 above identifies it" },
                                }
                            } }
                        }
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
        dcc: None,
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
