//! The Digital Calibration Certificate: the certificate as XML in PTB's
//! schema, DCC 3.3.0 (namespace `https://ptb.de/dcc`), its quantities in
//! D-SI 2.2 (`https://ptb.de/si`). `GET /v1/calibrations/{id}/certificate`
//! answers it to `Accept: application/xml`; the pages link it as
//! `/ui/calibrations/{id}/certificate.xml`.
//!
//! What fills each element (README "The Digital Calibration Certificate"
//! has the same table for users):
//!
//! * `coreData`: the laboratory's country (`--lab-country`), English as
//!   the one language, the calibration id as unique identifier, the item's
//!   receipt date, the performance date (begin and end: one tumble test),
//!   "laboratory" as the place, the date of the approving signature as
//!   the issue date, and, for a calibration that superseded another,
//!   `reportAmendedSubstituted` naming the replaced one;
//! * `items`: the item behind the sensor id (manufacturer, model, serial
//!   number, the sensor id, its condition on receipt);
//! * `calibrationLaboratory`: `--lab-name`, `--lab-address`, the country,
//!   `--lab-accreditation` as the laboratory code;
//! * `respPersons`: the reviewers who approved it (the last one the main
//!   signer); `customer`: the item's customer;
//! * `statements`: the metrological traceability, the decision rule with
//!   the conformity, that results relate only to the item, the due date
//!   when the customer agreed to one;
//! * `measurementResults`: the method, the reference standards with their
//!   certificates and parameters as `measuringEquipments`, the run
//!   temperatures and local g as `influenceConditions`, and every fused
//!   coefficient as `si:real` with its expanded uncertainty, coverage
//!   factor and probability.
//!
//! **Units.** The model is `U = Σ k·f(a)` with `a` the specific force in
//! multiples of g — a ratio, unit one — so every coefficient carries the
//! output's unit (`ki` in mA per unit of `a_i/g` is what the printed
//! certificate calls mA/g). The output unit is written in D-SI where it is an
//! SI unit accelcal recognises (`mA` → `\milli\ampere`), `\one` for counts,
//! and otherwise as a non-D-SI unit, `|` followed by the submission's text
//! (`|LSB`), which D-SI readers treat as such.
//!
//! A triad's calibration has the same administrative data and its own
//! measurement results ([`super::triad_dcc`]); [`document`] writes either.
//!
//! A DCC is issued only for an **approved** calibration (it names the
//! persons responsible), and only when the laboratory's name and country
//! and the item's customer are recorded: the schema requires them.

use axum::http::{HeaderMap, header};
use maud::{Markup, PreEscaped, html};

use super::certificate::{Context, PAPER};
use super::format::value_and_uncertainty;
use super::result::{Covered, ResultDoc};
use crate::domain::review::{Action, Signature, State};
use crate::http::problem::{Kind, Problem};

/// The DCC schema's namespace.
pub const DCC_NS: &str = "https://ptb.de/dcc";
/// D-SI's namespace.
pub const SI_NS: &str = "https://ptb.de/si";
/// The DCC schema version written.
pub const SCHEMA_VERSION: &str = "3.3.0";

/// Why no DCC can be issued for a calibration, as a problem.
fn refuse(kind: Kind, detail: String) -> Problem {
    Problem::new(kind, detail)
}

/// Checks that a DCC can be made of this calibration: approved, with the
/// laboratory's name and country configured and a customer recorded.
pub fn issuable(c: &Context) -> Result<(), Problem> {
    if c.state != State::Approved {
        return Err(refuse(
            Kind::StateConflict,
            format!(
                "the calibration is {}: a Digital Calibration Certificate is issued only for an \
                 approved calibration, since it names the persons responsible for it",
                c.state.as_str()
            ),
        ));
    }
    let mut missing = Vec::new();
    if c.laboratory.name.is_none() {
        missing.push("the laboratory's name (--lab-name)");
    }
    if c.laboratory.country.is_none() {
        missing.push("the laboratory's country (--lab-country)");
    }
    if c.customer.is_none() {
        missing.push(
            "the item's customer (PUT /v1/customers/{id}, then PUT /v1/sensors/{id}/item with it)",
        );
    }
    if missing.is_empty() {
        Ok(())
    } else {
        Err(refuse(
            Kind::Incomplete,
            format!(
                "a Digital Calibration Certificate needs {}, which {} not recorded",
                missing.join(" and "),
                if missing.len() == 1 { "is" } else { "are" }
            ),
        ))
    }
}

/// `text` with the characters XML 1.0 cannot carry removed (control
/// characters other than tab, line feed and carriage return).
fn xml_text(text: &str) -> String {
    text.chars()
        .filter(|c| !c.is_control() || matches!(c, '\t' | '\n' | '\r'))
        .collect()
}

/// `dcc:content` in English: the inside of every `dcc:textType` and
/// `dcc:richContentType` accelcal writes.
pub fn content(text: &str) -> Markup {
    html! { dcc:content lang="en" { (xml_text(text)) } }
}

/// The output unit in D-SI: prefixed SI units accelcal recognises, `\one`
/// for counts, and `|unit` (a non-D-SI unit) otherwise.
pub fn dsi_unit(unit: &str) -> String {
    let u = unit.trim();
    match u {
        "m/s2" | "m/s^2" | "m/s²" | "m s-2" | "m·s⁻²" => {
            return r"\metre\second\tothe{-2}".to_owned();
        }
        "1" | "LSB" | "lsb" | "counts" | "count" | "digits" => return r"\one".to_owned(),
        _ => {}
    }
    const BASES: [(&str, &str); 6] = [
        ("A", r"\ampere"),
        ("V", r"\volt"),
        ("Hz", r"\hertz"),
        ("W", r"\watt"),
        ("Ω", r"\ohm"),
        ("ohm", r"\ohm"),
    ];
    const PREFIXES: [(&str, &str); 6] = [
        ("", ""),
        ("k", r"\kilo"),
        ("m", r"\milli"),
        ("µ", r"\micro"),
        ("u", r"\micro"),
        ("n", r"\nano"),
    ];
    for (symbol, base) in BASES {
        if let Some(prefix) = u.strip_suffix(symbol)
            && let Some((_, p)) = PREFIXES.iter().find(|(s, _)| *s == prefix)
        {
            return format!("{p}{base}");
        }
    }
    let plain: String = u.chars().filter(|c| !c.is_whitespace()).collect();
    format!("|{}", if plain.is_empty() { "output" } else { &plain })
}

/// A number as D-SI's `decimalType` reads it (`-0.0123`, `1.2e-9`): the
/// shortest text that reads back as the same number.
fn decimal(v: f64) -> String {
    format!("{v}")
}

/// A coverage probability as D-SI's `probabilityValueType` (no exponent,
/// four decimals).
fn probability(p: f64) -> String {
    format!("{p:.4}")
}

/// The coverage factor as D-SI's `kValueType` (at least 1, no exponent).
fn coverage_factor(k: f64) -> String {
    format!("{}", k.max(1.0))
}

/// What each term is, for its `dcc:name`.
fn term_meaning(t: accelcal_core::Term) -> &'static str {
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

/// The DCC conformity of a decision's verdict: `conditional` splits by
/// whether the value itself lies within the limits.
fn conformity(verdict: &str, value: f64, min: Option<f64>, max: Option<f64>) -> &'static str {
    match verdict {
        "pass" => "pass",
        "fail" => "fail",
        _ if min.is_none_or(|m| value >= m) && max.is_none_or(|m| value <= m) => "conditionalPass",
        _ => "conditionalFail",
    }
}

/// The date part of an RFC 3339 instant (`2026-11-22`).
fn date(instant: &str) -> &str {
    instant.get(..10).unwrap_or(instant)
}

/// A `dcc:location` holding one line of address, and the country if known.
fn location(address: Option<&str>, country: Option<&str>) -> Markup {
    html! {
        dcc:location {
            dcc:further { (content(address.unwrap_or("no address recorded"))) }
            @if let Some(c) = country { dcc:countryCode { (c) } }
        }
    }
}

/// One `si:real` with its expanded uncertainty when there is one (`U`
/// with its coverage factor and probability).
pub fn real(label: &str, value: f64, unit: &str, expanded: Option<(f64, Covered)>) -> Markup {
    let (v, u) = match expanded {
        Some((u, _)) if u.is_finite() && u > 0.0 => {
            let (v, u) = value_and_uncertainty(value, u);
            (v, Some(u))
        }
        _ => (decimal(value), None),
    };
    html! {
        si:real {
            si:label { (label) }
            si:value { (v) }
            si:unit { (unit) }
            @if let (Some(u), Some((_, c))) = (u, expanded) {
                si:measurementUncertaintyUnivariate { si:expandedMU {
                    si:valueExpandedMU { (u) }
                    si:coverageFactor { (coverage_factor(c.k)) }
                    si:coverageProbability { (probability(c.p)) }
                    si:distribution { "normal" }
                } }
            }
        }
    }
}

/// A value with a standard uncertainty (a standard's parameter).
fn real_standard(label: &str, value: f64, unit: &str, std: Option<f64>) -> Markup {
    html! {
        si:real {
            si:label { (label) }
            si:value { (decimal(value)) }
            si:unit { (unit) }
            @if let Some(s) = std.filter(|s| s.is_finite() && *s >= 0.0) {
                si:measurementUncertaintyUnivariate { si:standardMU {
                    si:valueStandardMU { (decimal(s)) }
                    si:distribution { "normal" }
                } }
            }
        }
    }
}

/// The approving signatures: the persons responsible.
fn approvals(signatures: &[Signature]) -> Vec<&Signature> {
    signatures
        .iter()
        .filter(|s| s.action == Action::Approve)
        .collect()
}

/// The statement of conformity of a judged calibration.
pub struct Judged<'a> {
    /// `simple` or `guarded`.
    pub rule: &'a str,
    /// The worst verdict.
    pub verdict: &'a str,
    /// The worst DCC conformity of the limited terms or elements.
    pub worst: &'static str,
}

impl<'a> Judged<'a> {
    /// The statement of a decision whose limited quantities give
    /// `(verdict, value, min, max)`.
    pub fn of(
        rule: &'a str,
        verdict: &'a str,
        each: impl Iterator<Item = (&'a str, f64, Option<f64>, Option<f64>)>,
    ) -> Self {
        const ORDER: [&str; 4] = ["pass", "conditionalPass", "conditionalFail", "fail"];
        let worst = each
            .map(|(v, x, min, max)| conformity(v, x, min, max))
            .max_by_key(|c| ORDER.iter().position(|x| x == c))
            .unwrap_or("pass");
        Judged {
            rule,
            verdict,
            worst,
        }
    }
}

/// What the DCC's administrative data reads of a calibration, of either
/// kind.
pub struct Admin<'a> {
    /// The calibration.
    pub id: uuid::Uuid,
    /// The item's sensor id.
    pub sensor_id: &'a str,
    /// What the item is called (`Accelerometer`, `Accelerometer triad`).
    pub item: &'static str,
    /// When performed (RFC 3339).
    pub performed_at: &'a str,
    /// When the item was received, if stated.
    pub item_received_at: Option<&'a str>,
    /// Its condition on receipt, if stated.
    pub item_condition: Option<&'a str>,
    /// The calibration it supersedes.
    pub supersedes: Option<&'a crate::domain::review::Supersedes>,
    /// The reference standards, as used.
    pub standards: &'a [crate::domain::standards::UsedStandard],
    /// The decision, when judged.
    pub judged: Option<Judged<'a>>,
    /// The due date, when judged.
    pub due_at: Option<&'a str>,
}

impl<'a> Admin<'a> {
    /// A single-axis calibration's.
    fn of(d: &'a ResultDoc) -> Self {
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
}

/// The DCC document of a single-axis calibration ([`issuable`] must have
/// passed).
pub fn render(d: &ResultDoc, c: &Context) -> String {
    document(&Admin::of(d), c, &results(d))
}

/// The DCC of the calibration `a` describes, with its measurement
/// results `results`.
pub fn document(d: &Admin<'_>, c: &Context, results: &Markup) -> String {
    let approvals = approvals(&c.signatures);
    // Issued with its approval; an amendment when it was amended.
    let issued = match &c.amendment {
        Some(_) => c.issued.to_string(),
        None => approvals
            .last()
            .map(|s| s.signed_at.to_string())
            .unwrap_or_else(|| c.issued.to_string()),
    };
    let country = c.laboratory.country.as_deref();
    let lab_name = c.laboratory.name.as_deref().unwrap_or("");
    let doc = html! {
        (PreEscaped("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"))
        dcc:digitalCalibrationCertificate "xmlns:dcc"=(DCC_NS) "xmlns:si"=(SI_NS) schemaVersion=(SCHEMA_VERSION) {
            dcc:administrativeData {
                dcc:dccSoftware { dcc:software {
                    dcc:name { (content("accelcal")) }
                    dcc:release { (env!("CARGO_PKG_VERSION")) }
                    dcc:type { "application" }
                } }
                dcc:coreData {
                    dcc:countryCodeISO3166_1 { (country.unwrap_or("")) }
                    dcc:usedLangCodeISO639_1 { "en" }
                    dcc:mandatoryLangCodeISO639_1 { "en" }
                    dcc:uniqueIdentifier { (c.identifier(&d.id)) }
                    dcc:identifications {
                        dcc:identification {
                            dcc:issuer { "calibrationLaboratory" }
                            dcc:value { (c.submission_sha256) }
                            dcc:name { (content("SHA-256 of the stored submission")) }
                        }
                        dcc:identification {
                            dcc:issuer { "calibrationLaboratory" }
                            dcc:value { (xml_text(&c.url)) }
                            dcc:name { (content("This certificate's URL")) }
                        }
                    }
                    @if let Some(r) = d.item_received_at { dcc:receiptDate { (date(r)) } }
                    dcc:beginPerformanceDate { (date(d.performed_at)) }
                    dcc:endPerformanceDate { (date(d.performed_at)) }
                    dcc:performanceLocation { "laboratory" }
                    dcc:issueDate { (date(&issued)) }
                    @if let Some(amends) = c.amends(&d.id) {
                        dcc:reportAmendedSubstituted {
                            dcc:typeOfChange { "amended" }
                            dcc:replacedUniqueIdentifier { (amends) }
                        }
                    } @else if let Some(s) = d.supersedes {
                        dcc:reportAmendedSubstituted {
                            dcc:typeOfChange { "substituted" }
                            dcc:replacedUniqueIdentifier { (s.calibration_id) }
                        }
                    }
                }
                (items(d, c))
                dcc:calibrationLaboratory {
                    @if let Some(a) = &c.laboratory.accreditation {
                        dcc:calibrationLaboratoryCode { (xml_text(a)) }
                    }
                    dcc:contact {
                        dcc:name { (content(lab_name)) }
                        (location(c.laboratory.address.as_deref(), country))
                    }
                }
                dcc:respPersons {
                    @for (n, s) in approvals.iter().enumerate() {
                        dcc:respPerson {
                            dcc:person { dcc:name { (content(s.holder.as_deref().unwrap_or(&s.token_id))) } }
                            dcc:description { (content(&format!(
                                "{} (token {}, signed {}){}",
                                s.meaning,
                                s.token_id,
                                s.signed_at,
                                s.comment.as_deref().map_or(String::new(), |c| format!(": {c}"))
                            ))) }
                            dcc:role { "reviewer" }
                            dcc:mainSigner { (n + 1 == approvals.len()) }
                        }
                    }
                }
                @if let Some(cu) = &c.customer {
                    dcc:customer {
                        dcc:name { (content(&cu.name)) }
                        (location(cu.address.as_deref(), None))
                    }
                }
                (statements(d, c))
            }
            dcc:measurementResults { (results) }
        }
    };
    doc.into_string()
}

/// A single-axis calibration's `dcc:measurementResult`: the method, the
/// standards, the influence conditions and every fused coefficient.
fn results(d: &ResultDoc) -> Markup {
    let unit = dsi_unit(&d.unit);
    let statement = d
        .uncertainty
        .as_ref()
        .map(super::certificate::coverage_statement);
    html! {
                dcc:measurementResult {
                    dcc:name { (content("Static model of the accelerometer")) }
                    dcc:description {
                        (content(&format!(
                            "Fused coefficients of the model U = Σ k·f(a), with terms {}, the output U in {} and \
                             the specific force a in multiples of the local g (unit one): each coefficient is in \
                             the output's unit per unit of its regressor. Values are rounded to the second \
                             significant digit of their expanded uncertainty.",
                            d.model.join(", "),
                            d.unit
                        )))
                    }
                    dcc:usedMethods { dcc:usedMethod {
                        dcc:name { (content("Tumble test in the 1 g field, least squares per run, batch-estimation fusion")) }
                        dcc:description { (content(&format!(
                            "Tumble test on a dividing head ({} mount, {} positions, {} runs), the static model identified \
                             from each run by least squares and the runs fused by batch estimation ({} batches, \
                             inverse-variance weighting of batch means). Uncertainty after the GUM: the fused standard \
                             error, the stand's indexing error, the uncertainty of gravity and, when the lack-of-fit test \
                             finds the model short of the data, the model's own standard error, combined in quadrature \
                             and expanded{}.",
                            d.mount, d.positions.len(), d.runs.len(), d.batches,
                            statement.unwrap_or_default()
                        ))) }
                        dcc:norm { "ISO/IEC Guide 98-3 (GUM)" }
                        dcc:reference { (PAPER) }
                    } }
                    (equipment(&d.standards))
                    (conditions(d.temperatures_c.as_deref(), &d.standards))
                    dcc:results { dcc:result {
                        dcc:name { (content("Fused coefficients")) }
                        dcc:data {
                            @for (t, v) in d.fused.coefficients.iter() {
                                @let expanded = d.uncertainty.as_ref()
                                    .and_then(|u| u.terms.get(t).map(|b| (b.expanded, b.covered(u.coverage_factor))));
                                dcc:quantity {
                                    dcc:name { (content(&format!("{} — {} ({})", t.name(), term_meaning(t), super::format::term_unit(t, &d.unit)))) }
                                    (real(t.name(), *v, &unit, expanded))
                                    (meta_data(
                                        expanded.map(|(_, c)| c),
                                        &super::format::term_unit(t, &d.unit),
                                        d.decision.as_ref().and_then(|dec| dec.terms.get(t).map(|x| Judgement {
                                            rule: &dec.rule, verdict: &x.verdict, value: x.value, min: x.min, max: x.max,
                                        })),
                                    ))
                                }
                            }
                        }
                    } }
                }
    }
}

/// A judged quantity: the rule, its verdict, value and limits.
pub struct Judgement<'a> {
    /// `simple` or `guarded`.
    pub rule: &'a str,
    /// `pass`, `conditional` or `fail`.
    pub verdict: &'a str,
    /// The value judged.
    pub value: f64,
    /// Lower limit.
    pub min: Option<f64>,
    /// Upper limit.
    pub max: Option<f64>,
}

/// A quantity's `dcc:measurementMetaData`: how its expanded uncertainty
/// was formed (`u_c`, `ν_eff`, `k`, `p`) and, when judged, its limits and
/// conformity; nothing when neither.
pub fn meta_data(covered: Option<Covered>, unit: &str, judged: Option<Judgement<'_>>) -> Markup {
    if covered.is_none() && judged.is_none() {
        return html! {};
    }
    html! {
        dcc:measurementMetaData {
            @if let Some(c) = covered {
                dcc:metaData {
                    dcc:name { (content("Combined standard uncertainty, effective degrees of freedom, coverage")) }
                    dcc:declaration { (content(&format!(
                        "u_c = {} {unit}; ν_eff = {} (Welch–Satterthwaite, GUM G.2b); k = {}; p = {}",
                        decimal(c.combined),
                        super::format::dof(c.effective_dof),
                        coverage_factor(c.k),
                        probability(c.p),
                    ))) }
                }
            }
            @if let Some(j) = judged {
                (conformity_data(j.rule, unit, j.verdict, j.value, j.min, j.max))
            }
        }
    }
}

/// A `dcc:metaData` of a quantity's limits and conformity.
fn conformity_data(
    rule: &str,
    unit: &str,
    verdict: &str,
    value: f64,
    min: Option<f64>,
    max: Option<f64>,
) -> Markup {
    html! {
        dcc:metaData {
            dcc:name { (content("Conformity with the sensor type's limits")) }
            dcc:declaration { (content(&format!(
                "limits {} to {} {unit}, {rule} rule (ILAC-G8)",
                min.map_or("−∞".into(), decimal),
                max.map_or("+∞".into(), decimal),
            ))) }
            dcc:conformity { (conformity(verdict, value, min, max)) }
        }
    }
}

/// `dcc:items`: the item behind the sensor id.
fn items(d: &Admin<'_>, c: &Context) -> Markup {
    let item = c.item.as_ref();
    html! {
        dcc:items { dcc:item {
            @let described = item.map(|i| i.describe()).filter(|_| item.is_some_and(|i| {
                i.manufacturer.is_some() || i.model.is_some() || i.serial.is_some()
            }));
            dcc:name { (content(&format!("{} {}", d.item, described.unwrap_or_else(|| d.sensor_id.to_owned())))) }
            @if let Some(cond) = d.item_condition {
                dcc:description { (content(&format!("Condition on receipt: {cond}"))) }
            }
            @if let Some(m) = item.and_then(|i| i.manufacturer.as_deref()) {
                dcc:manufacturer { dcc:name { (content(m)) } }
            }
            @if let Some(m) = item.and_then(|i| i.model.as_deref()) {
                dcc:model { (xml_text(m)) }
            }
            dcc:identifications {
                @if let Some(s) = item.and_then(|i| i.serial.as_deref()) {
                    dcc:identification {
                        dcc:issuer { "manufacturer" }
                        dcc:value { (xml_text(s)) }
                        dcc:name { (content("Serial number")) }
                    }
                }
                dcc:identification {
                    dcc:issuer { "calibrationLaboratory" }
                    dcc:value { (xml_text(d.sensor_id)) }
                    dcc:name { (content("Sensor id")) }
                }
            }
        } }
    }
}

/// `dcc:statements`: traceability, conformity, the item-only statement, the
/// due date when agreed.
fn statements(d: &Admin<'_>, c: &Context) -> Markup {
    let due_agreed = c.customer.as_ref().is_none_or(|cu| cu.due_date_agreed);
    html! {
        dcc:statements {
            dcc:statement {
                dcc:name { (content("Metrological traceability")) }
                @if d.standards.is_empty() {
                    dcc:traceable { "false" }
                    dcc:declaration { (content("No reference standard was named with this calibration: this certificate does not establish the metrological traceability of its results.")) }
                } @else {
                    dcc:traceable { "true" }
                    dcc:declaration {
                        (content("The results are traceable to the SI through the reference standards listed under measuringEquipments, each in calibration when the test was performed."))
                        @for u in d.standards {
                            (content(&format!("{} (certificate {} of {}): {}", u.standard_id, u.certificate.number, u.certificate.issued_by, u.parameters.traceability)))
                        }
                    }
                }
            }
            @if let Some(a) = &c.amendment {
                dcc:statement {
                    dcc:name { (content(&format!("Amendment {}", a.number))) }
                    dcc:declaration { (content(&format!(
                        "This certificate (revision {}) amends and replaces {}. Reason: {}",
                        a.number + 1,
                        c.amends(&d.id).unwrap_or_default(),
                        a.reason
                    ))) }
                }
            }
            dcc:statement {
                dcc:name { (content("Scope of the results")) }
                dcc:declaration { (content("The results relate only to the item calibrated.")) }
            }
            @if let Some(dec) = &d.judged {
                dcc:statement {
                    dcc:name { (content("Statement of conformity")) }
                    dcc:declaration { (content(&format!(
                        "Decision rule: {} acceptance after ILAC-G8:2019{}; verdict {}.",
                        dec.rule,
                        if dec.rule == "guarded" { " (guard band w = U)" } else { " (the value alone against the limits)" },
                        dec.verdict
                    ))) }
                    dcc:conformity { (dec.worst) }
                }
            }
            @if let (true, Some(due)) = (due_agreed, d.due_at) {
                dcc:statement {
                    dcc:name { (content("Recalibration due")) }
                    dcc:declaration { (content("Recalibration is due by the date given, as agreed with the customer.")) }
                    dcc:date { (date(due)) }
                }
            }
        }
    }
}

/// `dcc:measuringEquipments`: the reference standards used.
pub fn equipment(standards: &[crate::domain::standards::UsedStandard]) -> Markup {
    html! {
        @if !standards.is_empty() {
            dcc:measuringEquipments {
                @for u in standards {
                    dcc:measuringEquipment {
                        dcc:name { (content(&format!("{} ({}): {}", u.standard_id, u.role, u.description))) }
                        dcc:description { (content(&format!(
                            "{}; calibrated {} by {}, certificate {}; due {}. {}",
                            u.kind.as_str(),
                            date(&u.certificate.calibrated_at.to_string()),
                            u.certificate.issued_by,
                            u.certificate.number,
                            date(&u.due_at.to_string()),
                            u.parameters.traceability
                        ))) }
                        dcc:identifications {
                            dcc:identification {
                                dcc:issuer { "calibrationLaboratory" }
                                dcc:value { (xml_text(&u.standard_id)) }
                                dcc:name { (content("Standard id")) }
                            }
                            @if let Some(s) = &u.serial {
                                dcc:identification {
                                    dcc:issuer { "manufacturer" }
                                    dcc:value { (xml_text(s)) }
                                    dcc:name { (content("Serial number")) }
                                }
                            }
                            dcc:identification {
                                dcc:issuer { "other" }
                                dcc:value { (xml_text(&u.certificate.number)) }
                                dcc:name { (content(&format!("Calibration certificate of {}", u.certificate.issued_by))) }
                            }
                        }
                        @let quantities = standard_quantities(u);
                        @if !quantities.is_empty() {
                            dcc:measuringEquipmentQuantities {
                                @for q in quantities { (q) }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A standard's parameters as `dcc:measuringEquipmentQuantity` elements.
fn standard_quantities(u: &crate::domain::standards::UsedStandard) -> Vec<Markup> {
    let mut out = Vec::new();
    let mut push = |name: &str, r: Markup| {
        out.push(html! { dcc:measuringEquipmentQuantity { dcc:name { (content(name)) } (r) } });
    };
    if let Some(a) = u.parameters.angle_std_arcsec {
        push(
            "Indexing error (1σ)",
            real_standard("indexing", a, r"\arcsecond", None),
        );
    }
    if let Some(g) = u.parameters.gravity_m_s2 {
        push(
            "Local gravity",
            real_standard(
                "g",
                g,
                r"\metre\second\tothe{-2}",
                u.parameters.gravity_rel_std.map(|r| r * g),
            ),
        );
    } else if let Some(r) = u.parameters.gravity_rel_std {
        push(
            "Relative uncertainty of gravity (1σ)",
            real_standard("gravity_rel_std", r, r"\one", None),
        );
    }
    if let Some(t) = u.parameters.temperature_std_c {
        push(
            "Thermometer uncertainty (1σ)",
            real_standard("temperature_std", t, r"\kelvin", None),
        );
    }
    out
}

/// `dcc:influenceConditions`: the run temperatures and local g.
pub fn conditions(
    temperatures_c: Option<&[f64]>,
    standards: &[crate::domain::standards::UsedStandard],
) -> Markup {
    let temps = temperatures_c.filter(|t| !t.is_empty());
    let gravity = standards
        .iter()
        .find(|u| u.role == "gravity")
        .and_then(|u| {
            u.parameters
                .gravity_m_s2
                .map(|g| (g, u.parameters.gravity_rel_std.map(|r| r * g)))
        });
    html! {
        @if temps.is_some() || gravity.is_some() {
            dcc:influenceConditions {
                @if let Some(t) = temps {
                    @let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
                    @let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    @let thermometer = standards.iter().find(|u| u.role == "thermometer").and_then(|u| u.parameters.temperature_std_c);
                    dcc:influenceCondition {
                        dcc:name { (content("Ambient temperature over the runs")) }
                        dcc:data {
                            dcc:quantity {
                                dcc:name { (content("Lowest run temperature")) }
                                (real_standard("temperature_min", lo, r"\degreecelsius", thermometer))
                            }
                            dcc:quantity {
                                dcc:name { (content("Highest run temperature")) }
                                (real_standard("temperature_max", hi, r"\degreecelsius", thermometer))
                            }
                        }
                    }
                }
                @if let Some((g, std)) = gravity {
                    dcc:influenceCondition {
                        dcc:name { (content("Local gravity")) }
                        dcc:data { dcc:quantity {
                            dcc:name { (content("Local acceleration due to gravity")) }
                            (real_standard("g", g, r"\metre\second\tothe{-2}", std))
                        } }
                    }
                }
            }
        }
    }
}

/// Whether a request's `Accept` prefers XML (`application/xml` or
/// `text/xml`) to HTML: by quality, ties going to HTML; without an
/// `Accept`, HTML.
pub fn prefers_xml(headers: &HeaderMap) -> bool {
    let mut xml = 0.0f32;
    let mut html = 0.0f32;
    for accept in headers.get_all(header::ACCEPT) {
        let Ok(accept) = accept.to_str() else {
            continue;
        };
        for range in accept.split(',') {
            let mut parts = range.split(';');
            let media = parts.next().unwrap_or("").trim().to_ascii_lowercase();
            let q = parts
                .filter_map(|p| p.trim().strip_prefix("q="))
                .find_map(|q| q.trim().parse::<f32>().ok())
                .unwrap_or(1.0);
            match media.as_str() {
                "application/xml" | "text/xml" => xml = xml.max(q),
                "text/html" | "text/*" | "*/*" => html = html.max(q),
                _ => {}
            }
        }
    }
    xml > html
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_read_as_d_si() {
        assert_eq!(dsi_unit("mA"), r"\milli\ampere");
        assert_eq!(dsi_unit("µA"), r"\micro\ampere");
        assert_eq!(dsi_unit("uA"), r"\micro\ampere");
        assert_eq!(dsi_unit("V"), r"\volt");
        assert_eq!(dsi_unit("mV"), r"\milli\volt");
        assert_eq!(dsi_unit("kHz"), r"\kilo\hertz");
        assert_eq!(dsi_unit("m/s²"), r"\metre\second\tothe{-2}");
        assert_eq!(dsi_unit("LSB"), r"\one");
        assert_eq!(dsi_unit("output"), "|output");
        assert_eq!(dsi_unit("deg F"), "|degF");
        assert_eq!(dsi_unit("mmA"), "|mmA");
    }

    #[test]
    fn numbers_match_d_si_patterns() {
        assert_eq!(probability(0.9545), "0.9545");
        assert_eq!(probability(0.883_883_476_483_184_4), "0.8839");
        assert_eq!(coverage_factor(2.0), "2");
        assert_eq!(coverage_factor(2.5), "2.5");
        assert_eq!(decimal(-1.25e-7), "-0.000000125");
    }

    #[test]
    fn conditional_verdicts_split_by_the_value() {
        assert_eq!(conformity("pass", 0.0, None, None), "pass");
        assert_eq!(conformity("fail", 0.0, None, None), "fail");
        assert_eq!(
            conformity("conditional", 1.0, Some(0.0), Some(2.0)),
            "conditionalPass"
        );
        assert_eq!(
            conformity("conditional", 2.1, Some(0.0), Some(2.0)),
            "conditionalFail"
        );
        assert_eq!(
            conformity("conditional", -0.1, Some(0.0), None),
            "conditionalFail"
        );
    }

    #[test]
    fn accept_negotiation() {
        let h = |v: &str| {
            let mut m = HeaderMap::new();
            m.insert(
                header::ACCEPT,
                axum::http::HeaderValue::from_str(v).unwrap(),
            );
            m
        };
        assert!(!prefers_xml(&HeaderMap::new()));
        assert!(prefers_xml(&h("application/xml")));
        assert!(prefers_xml(&h("text/xml")));
        assert!(!prefers_xml(&h("text/html,application/xml;q=0.9")));
        assert!(prefers_xml(&h("application/xml, */*;q=0.1")));
        assert!(!prefers_xml(&h("*/*")));
        assert!(!prefers_xml(&h("application/xml;q=0.5, text/html")));
    }

    #[test]
    fn a_country_is_two_capital_letters() {
        use crate::http::Laboratory;
        assert_eq!(Laboratory::country_from("DE"), Ok("DE".to_owned()));
        for bad in ["de", "DEU", "D", "", "D1"] {
            assert!(Laboratory::country_from(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn text_drops_what_xml_cannot_carry() {
        assert_eq!(xml_text("a\u{1}b\tc\n"), "ab\tc\n");
    }
}
