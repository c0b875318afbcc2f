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
//! Written once for every kind of calibration over its [`Document`]
//! ([`super::document`]): the administrative data, and the measurement
//! result's quantities; a kind supplies its texts and quantities
//! ([`super::kinds`]).
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

use super::certificate::Context;
use super::document::{Admin, Document, conformity};
use super::format::value_and_uncertainty;
use super::result::Covered;
use super::xml::Xml;
use crate::domain::review::{Action, Signature, State};
use crate::http::problem::{Kind, Problem};

mod admin;
mod equipment;
mod quantities;

use admin::*;
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

/// The DCC of a calibration of any kind ([`issuable`] must have passed).
pub fn render(doc: &Document<'_>, c: &Context) -> String {
    document(&doc.admin, c, |x| results(x, doc))
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

/// A calibration's `dcc:measurementResult`: the kind's model and method,
/// the standards, the influence conditions and every measured quantity as
/// `si:real` in the output's unit, with how its uncertainty was formed and,
/// when judged, its conformity (a fixed quantity is not measured, so not
/// listed).
fn results(x: &mut Xml, doc: &Document<'_>) {
    let t = &doc.dcc;
    let unit = dsi_unit(&t.unit);
    let rule = doc.admin.judged.as_ref().map(|j| j.rule);
    x.el("dcc:measurementResult", |x| {
        rich(x, "dcc:name", t.name);
        rich(x, "dcc:description", &t.description);
        x.el("dcc:usedMethods", |x| {
            x.el("dcc:usedMethod", |x| {
                rich(x, "dcc:name", t.method_name);
                rich(x, "dcc:description", &t.method);
                x.text("dcc:norm", "ISO/IEC Guide 98-3 (GUM)");
                if let Some(r) = t.reference {
                    x.text("dcc:reference", r);
                }
            })
        });
        equipment(x, doc.admin.standards);
        conditions(
            x,
            t.temperatures.as_deref(),
            t.reference_c,
            doc.admin.standards,
        );
        x.el("dcc:results", |x| {
            x.el("dcc:result", |x| {
                rich(x, "dcc:name", t.results_name);
                x.el("dcc:data", |x| {
                    for q in doc.quantities.iter().filter(|q| q.fixed.is_none()) {
                        let judged = q.limited.as_ref().zip(rule).map(|(l, rule)| {
                            Judgement::of(rule, (&l.verdict, l.value, l.min, l.max))
                        });
                        x.el("dcc:quantity", |x| {
                            rich(
                                x,
                                "dcc:name",
                                &format!("{} — {} ({})", q.name, q.meaning, q.dcc_unit),
                            );
                            let unit = per_kelvin(&unit, q.per_kelvin);
                            real(x, &q.name, q.value, &unit, q.expanded.zip(q.covered));
                            meta_data(
                                x,
                                q.covered.filter(|c| c.combined.is_finite()),
                                &q.dcc_unit,
                                judged,
                            );
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
