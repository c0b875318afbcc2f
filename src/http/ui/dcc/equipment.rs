//! The DCC's measuring equipment (the reference standards with their
//! certificates and parameters) and influence conditions (temperatures,
//! local g).

use super::*;

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
pub(super) fn standard_quantities(
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
    reference_c: Option<f64>,
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
            // A temperature model's set points bound its valid range.
            let [name, lowest, highest] = match reference_c {
                None => [
                    "Ambient temperature over the runs",
                    "Lowest run temperature",
                    "Highest run temperature",
                ],
                Some(_) => [
                    "Temperature range of the model (its set points' span)",
                    "Lowest set point, T_min",
                    "Highest set point, T_max",
                ],
            };
            x.el("dcc:influenceCondition", |x| {
                rich(x, "dcc:name", name);
                x.el("dcc:data", |x| {
                    let c = r"\degreecelsius";
                    quantity(x, lowest, "temperature_min", lo, c, thermometer);
                    quantity(x, highest, "temperature_max", hi, c, thermometer);
                    if let Some(t) = reference_c {
                        let name = "Reference temperature of the polynomials, T_ref";
                        quantity(x, name, "temperature_ref", t, c, None);
                    }
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
