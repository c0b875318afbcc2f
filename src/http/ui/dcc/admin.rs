//! The DCC's administrative data: the core data, the items, the
//! laboratory, the persons responsible, the customer and the statements.

use super::*;

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
    pub(super) fn of(d: &'a ResultDoc) -> Self {
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

/// `dcc:items`: the item behind the sensor id.
pub(super) fn items(x: &mut Xml, d: &Admin<'_>, c: &Context) {
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
pub(super) fn statement(
    x: &mut Xml,
    name: &str,
    declarations: &[&str],
    more: impl FnOnce(&mut Xml),
) {
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
pub(super) fn statements(x: &mut Xml, d: &Admin<'_>, c: &Context) {
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
