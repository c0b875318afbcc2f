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

mod admin;
mod equipment;
mod quantities;

pub use admin::*;
pub use equipment::*;
pub use quantities::*;

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
mod tests;
