//! The DCC's administrative data: the core data, the items, the
//! laboratory, the persons responsible, the customer and the statements.

use super::*;

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
