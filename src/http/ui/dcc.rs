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
//! **Written by an XML writer** ([`super::xml`], over `quick-xml`): every
//! text node and attribute value escaped by it, and the characters XML 1.0
//! cannot carry refused at input (so only legacy rows could hold one; the
//! writer replaces it with U+FFFD).
//!
//! A DCC is issued only for an **approved** calibration (it names the
//! persons responsible), and only when the laboratory's name and country
//! and the item's customer are recorded: the schema requires them.

use axum::http::{HeaderMap, header};

use super::certificate::{Context, PAPER};
use super::format::value_and_uncertainty;
use super::result::{Covered, ResultDoc};
use super::xml::Xml;
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

/// `dcc:content` in English: the inside of every `dcc:textType` and
/// `dcc:richContentType` accelcal writes.
pub fn content(x: &mut Xml, text: &str) {
    x.el_attrs("dcc:content", &[("lang", "en")], |x| x.chars(text));
}

/// Element `element` (a `dcc:textType` or `dcc:richContentType`: a name,
/// a description, a declaration) holding `text` in English.
pub fn rich(x: &mut Xml, element: &str, text: &str) {
    x.el(element, |x| content(x, text));
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
fn location(x: &mut Xml, address: Option<&str>, country: Option<&str>) {
    x.el("dcc:location", |x| {
        rich(x, "dcc:further", address.unwrap_or("no address recorded"));
        if let Some(c) = country {
            x.text("dcc:countryCode", c);
        }
    });
}

/// One `si:real` with its expanded uncertainty when there is one (`U`
/// with its coverage factor and probability).
pub fn real(x: &mut Xml, label: &str, value: f64, unit: &str, expanded: Option<(f64, Covered)>) {
    let (v, u) = match expanded {
        Some((u, _)) if u.is_finite() && u > 0.0 => {
            let (v, u) = value_and_uncertainty(value, u);
            (v, Some(u))
        }
        _ => (decimal(value), None),
    };
    x.el("si:real", |x| {
        x.text("si:label", label);
        x.text("si:value", v);
        x.text("si:unit", unit);
        if let (Some(u), Some((_, c))) = (u, expanded) {
            x.el("si:measurementUncertaintyUnivariate", |x| {
                x.el("si:expandedMU", |x| {
                    x.text("si:valueExpandedMU", u);
                    x.text("si:coverageFactor", coverage_factor(c.k));
                    x.text("si:coverageProbability", probability(c.p));
                    x.text("si:distribution", "normal");
                })
            });
        }
    });
}

/// A value with a standard uncertainty (a standard's parameter).
fn real_standard(x: &mut Xml, label: &str, value: f64, unit: &str, std: Option<f64>) {
    x.el("si:real", |x| {
        x.text("si:label", label);
        x.text("si:value", decimal(value));
        x.text("si:unit", unit);
        if let Some(s) = std.filter(|s| s.is_finite() && *s >= 0.0) {
            x.el("si:measurementUncertaintyUnivariate", |x| {
                x.el("si:standardMU", |x| {
                    x.text("si:valueStandardMU", decimal(s));
                    x.text("si:distribution", "normal");
                })
            });
        }
    });
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
    document(&Admin::of(d), c, |x| results(x, d))
}

/// The DCC of the calibration `d` describes, its measurement results
/// written by `results`.
pub fn document(d: &Admin<'_>, c: &Context, results: impl FnOnce(&mut Xml)) -> String {
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
    let root = [
        ("xmlns:dcc", DCC_NS),
        ("xmlns:si", SI_NS),
        ("schemaVersion", SCHEMA_VERSION),
    ];
    let mut x = Xml::document();
    x.el_attrs("dcc:digitalCalibrationCertificate", &root, |x| {
        x.el("dcc:administrativeData", |x| {
            x.el("dcc:dccSoftware", |x| {
                x.el("dcc:software", |x| {
                    rich(x, "dcc:name", "accelcal");
                    x.text("dcc:release", env!("CARGO_PKG_VERSION"));
                    x.text("dcc:type", "application");
                })
            });
            x.el("dcc:coreData", |x| {
                x.text("dcc:countryCodeISO3166_1", country.unwrap_or(""));
                x.text("dcc:usedLangCodeISO639_1", "en");
                x.text("dcc:mandatoryLangCodeISO639_1", "en");
                x.text("dcc:uniqueIdentifier", c.identifier(&d.id));
                x.el("dcc:identifications", |x| {
                    identification(
                        x,
                        "calibrationLaboratory",
                        &c.submission_sha256,
                        "SHA-256 of the stored submission",
                    );
                    identification(x, "calibrationLaboratory", &c.url, "This certificate's URL");
                });
                if let Some(r) = d.item_received_at {
                    x.text("dcc:receiptDate", date(r));
                }
                x.text("dcc:beginPerformanceDate", date(d.performed_at));
                x.text("dcc:endPerformanceDate", date(d.performed_at));
                x.text("dcc:performanceLocation", "laboratory");
                x.text("dcc:issueDate", date(&issued));
                let replaced = match (c.amends(&d.id), d.supersedes) {
                    (Some(amends), _) => Some(("amended", amends)),
                    (None, Some(s)) => Some(("substituted", s.calibration_id.to_string())),
                    (None, None) => None,
                };
                if let Some((change, id)) = replaced {
                    x.el("dcc:reportAmendedSubstituted", |x| {
                        x.text("dcc:typeOfChange", change);
                        x.text("dcc:replacedUniqueIdentifier", id);
                    });
                }
            });
            items(x, d, c);
            x.el("dcc:calibrationLaboratory", |x| {
                if let Some(a) = &c.laboratory.accreditation {
                    x.text("dcc:calibrationLaboratoryCode", a);
                }
                x.el("dcc:contact", |x| {
                    rich(x, "dcc:name", lab_name);
                    location(x, c.laboratory.address.as_deref(), country);
                });
            });
            x.el("dcc:respPersons", |x| {
                for (n, s) in approvals.iter().enumerate() {
                    x.el("dcc:respPerson", |x| {
                        x.el("dcc:person", |x| {
                            rich(x, "dcc:name", s.holder.as_deref().unwrap_or(&s.token_id))
                        });
                        rich(
                            x,
                            "dcc:description",
                            &format!(
                                "{} (token {}, signed {}){}",
                                s.meaning,
                                s.token_id,
                                s.signed_at,
                                s.comment
                                    .as_deref()
                                    .map_or(String::new(), |c| format!(": {c}"))
                            ),
                        );
                        x.text("dcc:role", "reviewer");
                        x.text(
                            "dcc:mainSigner",
                            if n + 1 == approvals.len() {
                                "true"
                            } else {
                                "false"
                            },
                        );
                    });
                }
            });
            if let Some(cu) = &c.customer {
                x.el("dcc:customer", |x| {
                    rich(x, "dcc:name", &cu.name);
                    location(x, cu.address.as_deref(), None);
                });
            }
            statements(x, d, c);
        });
        x.el("dcc:measurementResults", results);
    });
    x.finish()
}

/// One `dcc:identification`: who issued `value`, and what it is.
fn identification(x: &mut Xml, issuer: &str, value: &str, name: &str) {
    x.el("dcc:identification", |x| {
        x.text("dcc:issuer", issuer);
        x.text("dcc:value", value);
        rich(x, "dcc:name", name);
    });
}

/// A single-axis calibration's `dcc:measurementResult`: the method, the
/// standards, the influence conditions and every fused coefficient.
fn results(x: &mut Xml, d: &ResultDoc) {
    let unit = dsi_unit(&d.unit);
    let statement = d
        .uncertainty
        .as_ref()
        .map(super::coverage::coverage_statement);
    x.el("dcc:measurementResult", |x| {
        rich(x, "dcc:name", "Static model of the accelerometer");
        rich(x, "dcc:description", &format!(
                    "Fused coefficients of the model U = Σ k·f(a), with terms {}, the output U in {} and \
                     the specific force a in multiples of the local g (unit one): each coefficient is in \
                     the output's unit per unit of its regressor. Values are rounded to the second \
                     significant digit of their expanded uncertainty.",
                    d.model.join(", "),
                    d.unit
                ));
        x.el("dcc:usedMethods", |x| {
            x.el("dcc:usedMethod", |x| {
                rich(x, "dcc:name", "Tumble test in the 1 g field, least squares per run, batch-estimation fusion");
                rich(x, "dcc:description", &format!(
                            "Tumble test on a dividing head ({} mount, {} positions, {} runs), the static model identified \
                             from each run by least squares and the runs fused by batch estimation ({} batches, \
                             inverse-variance weighting of batch means). Uncertainty after the GUM: the fused standard \
                             error, the stand's indexing error, the uncertainty of gravity and, when the lack-of-fit test \
                             finds the model short of the data, the model's own standard error, combined in quadrature \
                             and expanded{}.",
                            d.mount,
                            d.positions.len(),
                            d.runs.len(),
                            d.batches,
                            statement.unwrap_or_default()
                        ));
                x.text("dcc:norm", "ISO/IEC Guide 98-3 (GUM)");
                x.text("dcc:reference", PAPER);
            })
        });
        equipment(x, &d.standards);
        conditions(x, d.temperatures_c.as_deref(), &d.standards);
        x.el("dcc:results", |x| {
            x.el("dcc:result", |x| {
                rich(x, "dcc:name", "Fused coefficients");
                x.el("dcc:data", |x| {
                    for (t, v) in d.fused.coefficients.iter() {
                        let expanded = d.uncertainty.as_ref().and_then(|u| {
                            u.terms
                                .get(t)
                                .map(|b| (b.expanded, b.covered(u.coverage_factor)))
                        });
                        let term_unit = super::format::term_unit(t, &d.unit);
                        let judged = d.decision.as_ref().and_then(|dec| {
                            let j = dec.terms.get(t)?;
                            Some(Judgement::of(&dec.rule, (&j.verdict, j.value, j.min, j.max)))
                        });
                        x.el("dcc:quantity", |x| {
                            rich(x, "dcc:name", &format!("{} — {} ({term_unit})", t.name(), term_meaning(t)));
                            real(x, t.name(), *v, &unit, expanded);
                            meta_data(x, expanded.map(|(_, c)| c), &term_unit, judged);
                        });
                    }
                })
            })
        });
    });
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

impl<'a> Judgement<'a> {
    /// Under `rule`, the `(verdict, value, min, max)` of a judged
    /// coefficient or triad element.
    pub fn of(rule: &'a str, judged: (&'a str, f64, Option<f64>, Option<f64>)) -> Self {
        let (verdict, value, min, max) = judged;
        Judgement {
            rule,
            verdict,
            value,
            min,
            max,
        }
    }
}

/// A quantity's `dcc:measurementMetaData`: how its expanded uncertainty
/// was formed (`u_c`, `ν_eff`, `k`, `p`) and, when judged, its limits and
/// conformity; nothing when neither.
pub fn meta_data(x: &mut Xml, covered: Option<Covered>, unit: &str, judged: Option<Judgement<'_>>) {
    if covered.is_none() && judged.is_none() {
        return;
    }
    x.el("dcc:measurementMetaData", |x| {
        if let Some(c) = covered {
            x.el("dcc:metaData", |x| {
                rich(x, "dcc:name", "Combined standard uncertainty, effective degrees of freedom, coverage");
                x.el("dcc:declaration", |x| {
                    content(
                        x,
                        &format!(
                            "u_c = {} {unit}; ν_eff = {} (Welch–Satterthwaite, GUM G.2b); k = {}; p = {}",
                            decimal(c.combined),
                            super::format::dof(c.effective_dof),
                            coverage_factor(c.k),
                            probability(c.p),
                        ),
                    )
                });
            });
        }
        if let Some(j) = judged {
            x.el("dcc:metaData", |x| {
                rich(x, "dcc:name", "Conformity with the sensor type's limits");
                rich(x, "dcc:declaration", &format!(
                            "limits {} to {} {unit}, {} rule (ILAC-G8)",
                            j.min.map_or("−∞".into(), decimal),
                            j.max.map_or("+∞".into(), decimal),
                            j.rule,
                        ));
                x.text(
                    "dcc:conformity",
                    conformity(j.verdict, j.value, j.min, j.max),
                );
            });
        }
    });
}

/// `dcc:items`: the item behind the sensor id.
fn items(x: &mut Xml, d: &Admin<'_>, c: &Context) {
    let item = c.item.as_ref();
    let described = item
        .filter(|i| i.manufacturer.is_some() || i.model.is_some() || i.serial.is_some())
        .map(|i| i.describe());
    x.el("dcc:items", |x| {
        x.el("dcc:item", |x| {
            rich(
                x,
                "dcc:name",
                &format!(
                    "{} {}",
                    d.item,
                    described.unwrap_or_else(|| d.sensor_id.to_owned())
                ),
            );
            if let Some(cond) = d.item_condition {
                rich(
                    x,
                    "dcc:description",
                    &format!("Condition on receipt: {cond}"),
                );
            }
            if let Some(m) = item.and_then(|i| i.manufacturer.as_deref()) {
                x.el("dcc:manufacturer", |x| rich(x, "dcc:name", m));
            }
            if let Some(m) = item.and_then(|i| i.model.as_deref()) {
                x.text("dcc:model", m);
            }
            x.el("dcc:identifications", |x| {
                if let Some(s) = item.and_then(|i| i.serial.as_deref()) {
                    identification(x, "manufacturer", s, "Serial number");
                }
                identification(x, "calibrationLaboratory", d.sensor_id, "Sensor id");
            });
        })
    });
}

/// One `dcc:statement` named `name`: its declarations, then whatever
/// `more` writes (`dcc:traceable` goes before them, so it is written by
/// the caller).
fn statement(x: &mut Xml, name: &str, declarations: &[&str], more: impl FnOnce(&mut Xml)) {
    x.el("dcc:statement", |x| {
        rich(x, "dcc:name", name);
        x.el("dcc:declaration", |x| {
            for d in declarations {
                content(x, d);
            }
        });
        more(x);
    });
}

/// `dcc:statements`: traceability, conformity, the item-only statement, the
/// due date when agreed.
fn statements(x: &mut Xml, d: &Admin<'_>, c: &Context) {
    let due_agreed = c.customer.as_ref().is_none_or(|cu| cu.due_date_agreed);
    x.el("dcc:statements", |x| {
        x.el("dcc:statement", |x| {
            rich(x, "dcc:name", "Metrological traceability");
            if d.standards.is_empty() {
                x.text("dcc:traceable", "false");
                rich(x, "dcc:declaration", "No reference standard was named with this calibration: this certificate does \
                         not establish the metrological traceability of its results.");
            } else {
                x.text("dcc:traceable", "true");
                x.el("dcc:declaration", |x| {
                    content(
                        x,
                        "The results are traceable to the SI through the reference standards listed under \
                         measuringEquipments, each in calibration when the test was performed.",
                    );
                    for u in d.standards {
                        content(
                            x,
                            &format!(
                                "{} (certificate {} of {}): {}",
                                u.standard_id,
                                u.certificate.number,
                                u.certificate.issued_by,
                                u.parameters.traceability
                            ),
                        );
                    }
                });
            }
        });
        if let Some(a) = &c.amendment {
            let why = format!(
                "This certificate (revision {}) amends and replaces {}. Reason: {}",
                a.number + 1,
                c.amends(&d.id).unwrap_or_default(),
                a.reason
            );
            statement(x, &format!("Amendment {}", a.number), &[&why], |_| {});
        }
        statement(
            x,
            "Scope of the results",
            &["The results relate only to the item calibrated."],
            |_| {},
        );
        if let Some(dec) = &d.judged {
            let rule = format!(
                "Decision rule: {} acceptance after ILAC-G8:2019{}; verdict {}.",
                dec.rule,
                if dec.rule == "guarded" {
                    " (guard band w = U)"
                } else {
                    " (the value alone against the limits)"
                },
                dec.verdict
            );
            statement(x, "Statement of conformity", &[&rule], |x| {
                x.text("dcc:conformity", dec.worst)
            });
        }
        if let (true, Some(due)) = (due_agreed, d.due_at) {
            statement(
                x,
                "Recalibration due",
                &["Recalibration is due by the date given, as agreed with the customer."],
                |x| x.text("dcc:date", date(due)),
            );
        }
    });
}

/// `dcc:measuringEquipments`: the reference standards used.
pub fn equipment(x: &mut Xml, standards: &[crate::domain::standards::UsedStandard]) {
    if standards.is_empty() {
        return;
    }
    x.el("dcc:measuringEquipments", |x| {
        for u in standards {
            x.el("dcc:measuringEquipment", |x| {
                rich(
                    x,
                    "dcc:name",
                    &format!("{} ({}): {}", u.standard_id, u.role, u.description),
                );
                x.el("dcc:description", |x| {
                    content(
                        x,
                        &format!(
                            "{}; calibrated {} by {}, certificate {}; due {}. {}",
                            u.kind.as_str(),
                            date(&u.certificate.calibrated_at.to_string()),
                            u.certificate.issued_by,
                            u.certificate.number,
                            date(&u.due_at.to_string()),
                            u.parameters.traceability
                        ),
                    )
                });
                x.el("dcc:identifications", |x| {
                    identification(x, "calibrationLaboratory", &u.standard_id, "Standard id");
                    if let Some(s) = &u.serial {
                        identification(x, "manufacturer", s, "Serial number");
                    }
                    identification(
                        x,
                        "other",
                        &u.certificate.number,
                        &format!("Calibration certificate of {}", u.certificate.issued_by),
                    );
                });
                let quantities = standard_quantities(u);
                if !quantities.is_empty() {
                    x.el("dcc:measuringEquipmentQuantities", |x| {
                        for (name, label, value, unit, std) in quantities {
                            x.el("dcc:measuringEquipmentQuantity", |x| {
                                rich(x, "dcc:name", name);
                                real_standard(x, label, value, unit, std);
                            });
                        }
                    });
                }
            });
        }
    });
}

/// A standard's parameters as its `dcc:measuringEquipmentQuantity`
/// elements: name, label, value, D-SI unit and standard uncertainty.
fn standard_quantities(
    u: &crate::domain::standards::UsedStandard,
) -> Vec<(&'static str, &'static str, f64, &'static str, Option<f64>)> {
    let p = &u.parameters;
    let mut out = Vec::new();
    if let Some(a) = p.angle_std_arcsec {
        out.push(("Indexing error (1σ)", "indexing", a, r"\arcsecond", None));
    }
    if let Some(g) = p.gravity_m_s2 {
        let std = p.gravity_rel_std.map(|r| r * g);
        out.push(("Local gravity", "g", g, r"\metre\second\tothe{-2}", std));
    } else if let Some(r) = p.gravity_rel_std {
        let name = "Relative uncertainty of gravity (1σ)";
        out.push((name, "gravity_rel_std", r, r"\one", None));
    }
    if let Some(t) = p.temperature_std_c {
        let name = "Thermometer uncertainty (1σ)";
        out.push((name, "temperature_std", t, r"\kelvin", None));
    }
    out
}

/// `dcc:influenceConditions`: the run temperatures and local g.
pub fn conditions(
    x: &mut Xml,
    temperatures_c: Option<&[f64]>,
    standards: &[crate::domain::standards::UsedStandard],
) {
    let temps = temperatures_c.filter(|t| !t.is_empty());
    let gravity = standards
        .iter()
        .find(|u| u.role == "gravity")
        .and_then(|u| {
            u.parameters
                .gravity_m_s2
                .map(|g| (g, u.parameters.gravity_rel_std.map(|r| r * g)))
        });
    if temps.is_none() && gravity.is_none() {
        return;
    }
    let quantity = |x: &mut Xml, name: &str, label: &str, value: f64, unit: &str, std| {
        x.el("dcc:quantity", |x| {
            rich(x, "dcc:name", name);
            real_standard(x, label, value, unit, std);
        });
    };
    x.el("dcc:influenceConditions", |x| {
        if let Some(t) = temps {
            let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let thermometer = standards
                .iter()
                .find(|u| u.role == "thermometer")
                .and_then(|u| u.parameters.temperature_std_c);
            x.el("dcc:influenceCondition", |x| {
                rich(x, "dcc:name", "Ambient temperature over the runs");
                x.el("dcc:data", |x| {
                    let c = r"\degreecelsius";
                    quantity(
                        x,
                        "Lowest run temperature",
                        "temperature_min",
                        lo,
                        c,
                        thermometer,
                    );
                    quantity(
                        x,
                        "Highest run temperature",
                        "temperature_max",
                        hi,
                        c,
                        thermometer,
                    );
                });
            });
        }
        if let Some((g, std)) = gravity {
            x.el("dcc:influenceCondition", |x| {
                rich(x, "dcc:name", "Local gravity");
                x.el("dcc:data", |x| {
                    let unit = r"\metre\second\tothe{-2}";
                    quantity(x, "Local acceleration due to gravity", "g", g, unit, std);
                });
            });
        }
    });
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
}
