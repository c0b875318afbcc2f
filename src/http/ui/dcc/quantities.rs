//! The DCC's quantities in D-SI: units, values with their expanded
//! uncertainty, coverage and conformity (`si:real`), and the metadata that
//! states how each was judged.

use super::*;

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

/// D-SI unit `unit` per K^`d` (`\volt\kelvin\tothe{-1}`; `\one` per K is
/// `\kelvin\tothe{-1}`; a non-D-SI `|unit` is written `|unit/K^d`).
pub fn per_kelvin(unit: &str, d: i32) -> String {
    match (d, unit) {
        (0, _) => unit.to_owned(),
        (_, r"\one") => format!(r"\kelvin\tothe{{{}}}", -d),
        (_, u) if u.starts_with('|') => format!("{u}/K^{d}"),
        (_, u) => format!(r"{u}\kelvin\tothe{{{}}}", -d),
    }
}

/// A number as D-SI's `decimalType` reads it (`-0.0123`, `1.2e-9`): the
/// shortest text that reads back as the same number.
pub(super) fn decimal(v: f64) -> String {
    format!("{v}")
}

/// A coverage probability as D-SI's `probabilityValueType` (no exponent,
/// four decimals).
pub(super) fn probability(p: f64) -> String {
    format!("{p:.4}")
}

/// The coverage factor as D-SI's `kValueType` (at least 1, no exponent).
pub(super) fn coverage_factor(k: f64) -> String {
    format!("{}", k.max(1.0))
}

/// The date part of an RFC 3339 instant (`2026-11-22`).
pub(super) fn date(instant: &str) -> &str {
    instant.get(..10).unwrap_or(instant)
}

/// A `dcc:location` holding one line of address, and the country if known.
pub(super) fn location(x: &mut Xml, address: Option<&str>, country: Option<&str>) {
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
pub(super) fn real_standard(x: &mut Xml, label: &str, value: f64, unit: &str, std: Option<f64>) {
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
pub(super) fn approvals(signatures: &[Signature]) -> Vec<&Signature> {
    signatures
        .iter()
        .filter(|s| s.action == Action::Approve)
        .collect()
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
                            super::super::format::dof(c.effective_dof),
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
