//! A triad's temperature model as files (issue 45 item 5): what the
//! formats share — the model evaluated, the terms a firmware format
//! cannot carry and the refusal when dropping one matters — and the C
//! header, which, with the model's own JSON, carries all of it.
//!
//! **What PX4 and ArduPilot cannot carry.** Their thermal parameters
//! correct the offset alone: the temperature dependence of every element
//! of `S`,
//!
//! ```text
//! Δ(T) = S_mn(T) − S_mn(T_ref) = Σ_{d≥1} a_d x^d,   x = T − T_ref,
//! ```
//!
//! is dropped (the static calibration's `S` at `T_ref` stays). Its effect
//! over the range is `E = max |Δ(T)|` over `[T_min, T_max]`, found at an
//! end of the range or where `Δ'(T) = 0`; its expanded uncertainty there
//! is `U = k √(vᵀ C_a v)`, `v = (0, x, x², x³)`, with `k =`
//! [`COVERAGE_K`]. An element with `E > U` — a dependence the data show —
//! refuses the export ([`ThermalExportError::NotCarried`], a 409 naming
//! it); one within its uncertainty is said in the file and dropped.

use std::fmt::Write as _;

use accelcal_core::thermal::Polynomial;
use accelcal_core::triad::AXES;

use super::TriadThermalModel;
use super::at::stationary;
use crate::domain::triad_export::{ExportError, c_string};

/// The coverage factor of a dropped term's expanded uncertainty.
pub const COVERAGE_K: f64 = 2.0;

/// A term a format drops, and what dropping it costs.
#[derive(Clone, Debug, PartialEq)]
pub struct Dropped {
    /// The element, `S_xx` … `S_zz`.
    pub term: String,
    /// `E`, in outputs per g.
    pub effect: f64,
    /// `U` at the temperature of `E`.
    pub expanded: f64,
    /// Where `E` is, °C.
    pub at_c: f64,
}

/// Why a temperature model cannot be exported in a format.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ThermalExportError {
    /// The outputs are in no acceleration unit.
    #[error(transparent)]
    Unit(#[from] ExportError),
    /// Terms the format drops change more over the range than their
    /// expanded uncertainty.
    #[error(
        "{format} carries no temperature dependence of S, and over this model's range {} — \
         beyond the expanded uncertainty U (k = {COVERAGE_K}): dropping it would misread the \
         specific force; export `json` or `c`, which carry the whole model",
        said(dropped)
    )]
    NotCarried {
        /// The format.
        format: &'static str,
        /// The terms, the largest `E / U` first.
        dropped: Vec<Dropped>,
    },
}

/// `S_zz changes by 7.8e-2 (U 1.1e-3) at 60 C, S_xx …`.
fn said(dropped: &[Dropped]) -> String {
    dropped
        .iter()
        .map(|d| {
            format!(
                "{} changes by {:.2e} (U {:.2e}) at {} °C",
                d.term,
                d.effect,
                d.expanded,
                round(d.at_c)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A temperature to 0.01 K.
fn round(t: f64) -> f64 {
    (t * 100.0).round() / 100.0
}

/// `p` at `t` °C.
pub fn at(p: &Polynomial, t: f64) -> f64 {
    p.coefficients
        .iter()
        .rev()
        .fold(0.0, |acc, a| acc * (t - p.reference_c) + a)
}

/// `Δ(t)` of `p` and its standard uncertainty (module doc).
fn change(p: &Polynomial, t: f64) -> (f64, f64) {
    let x = t - p.reference_c;
    let v: Vec<f64> = (0..=p.degree)
        .map(|d| if d == 0 { 0.0 } else { x.powi(d as i32) })
        .collect();
    let value = v.iter().zip(&p.coefficients).map(|(v, a)| v * a).sum();
    let var: f64 = (0..v.len())
        .flat_map(|i| (0..v.len()).map(move |j| (i, j)))
        .map(|(i, j)| v[i] * p.covariance[i][j] * v[j])
        .sum();
    (value, var.max(0.0).sqrt())
}

/// Where `|Δ|` of `p` can be largest on its range: the ends, and where
/// `Δ′ = c′ = 0` within it.
fn candidates(p: &Polynomial) -> Vec<f64> {
    let mut ts = p.range_c.to_vec();
    ts.extend(stationary(p));
    ts
}

/// `E` and `U` of `p` (module doc), and where.
fn effect(p: &Polynomial, term: String) -> Dropped {
    candidates(p)
        .into_iter()
        .map(|t| {
            let (value, u) = change(p, t);
            Dropped {
                term: term.clone(),
                effect: value.abs(),
                expanded: COVERAGE_K * u,
                at_c: t,
            }
        })
        .fold(None::<Dropped>, |best, d| match best {
            Some(b) if b.effect >= d.effect => Some(b),
            _ => Some(d),
        })
        .expect("the range's ends")
}

/// Every element of `model`'s `S`, what dropping its temperature
/// dependence costs, by rows.
pub fn dropped(model: &TriadThermalModel) -> Vec<Dropped> {
    let mut out = Vec::with_capacity(9);
    for (m, row) in AXES.iter().enumerate() {
        for (n, column) in AXES.iter().enumerate() {
            out.push(effect(&model.s[m][n], format!("S_{row}{column}")));
        }
    }
    out
}

/// `Ok` with every dropped term when dropping them is within their
/// uncertainty; otherwise the refusal, naming those that are not.
pub fn carried(
    model: &TriadThermalModel,
    format: &'static str,
) -> Result<Vec<Dropped>, ThermalExportError> {
    let all = dropped(model);
    let mut beyond: Vec<Dropped> = all
        .iter()
        .filter(|d| d.effect > d.expanded)
        .cloned()
        .collect();
    if beyond.is_empty() {
        return Ok(all);
    }
    beyond.sort_by(|a, b| (b.effect / b.expanded).total_cmp(&(a.effect / a.expanded)));
    Err(ThermalExportError::NotCarried {
        format,
        dropped: beyond,
    })
}

/// The file's lines on what it drops: each element of `S`'s change over
/// the range against its expanded uncertainty.
pub fn not_carried_lines(out: &mut String, format: &str, dropped: &[Dropped]) {
    let _ = writeln!(
        out,
        "# NOT CARRIED: S(T) ({format} has no thermal scale factor or cross-axis term); each \
         element's largest change over the range, against its expanded uncertainty (k = \
         {COVERAGE_K}), all within it:"
    );
    for d in dropped {
        if d.effect == 0.0 {
            let _ = writeln!(out, "#   {} constant over the range", d.term);
        } else {
            let _ = writeln!(
                out,
                "#   {} changes by {:.3e} (U {:.3e}) at {} C",
                d.term,
                d.effect,
                d.expanded,
                round(d.at_c)
            );
        }
    }
}

/// The C header of `model`, described by `source`: every polynomial,
/// `a_0 … a_3` (zeros past its degree), about one `T_ref`.
pub fn c_header(model: &TriadThermalModel, source: &str) -> String {
    let poly = |p: &Polynomial| {
        let a: Vec<String> = (0..=3)
            .map(|d| format!("{:.12e}", p.coefficients.get(d).copied().unwrap_or(0.0)))
            .collect();
        format!("{{ {} }}", a.join(", "))
    };
    let [t_min, t_max] = model.b[0].range_c;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "/* accelcal triad temperature model (ACCELCAL_SOURCE says which). */"
    );
    for line in [
        "/*",
        " * Outputs u in ACCELCAL_UNIT (x, y, z); specific force g in g; T in deg C.",
        " *   u = b(T) + S(T) g, g = S(T)^-1 (u - b(T))",
        " *   e(T) = sum over d of P[d] * (T - ACCELCAL_T_REF)^d, d = 0..3, for every element",
        " *   e of b (ACCELCAL_B_POLY[m]) and S (ACCELCAL_S_POLY[m][n], row m is axis m);",
        " *   P[d] in ACCELCAL_UNIT (per g for S) per K^d.",
        " * Valid for ACCELCAL_T_MIN <= T <= ACCELCAL_T_MAX: the set points' span.",
        " */",
        "#ifndef ACCELCAL_TRIAD_THERMAL_H",
        "#define ACCELCAL_TRIAD_THERMAL_H",
    ] {
        let _ = writeln!(out, "{line}");
    }
    let _ = writeln!(
        out,
        "static const char ACCELCAL_SOURCE[] = \"{}\";",
        c_string(source)
    );
    let _ = writeln!(
        out,
        "static const char ACCELCAL_UNIT[] = \"{}\";",
        c_string(&model.unit)
    );
    for (name, value) in [
        ("T_REF", model.b[0].reference_c),
        ("T_MIN", t_min),
        ("T_MAX", t_max),
    ] {
        let _ = writeln!(out, "static const double ACCELCAL_{name} = {value:.6};");
    }
    let _ = writeln!(out, "static const double ACCELCAL_B_POLY[3][4] = {{");
    for (m, p) in model.b.iter().enumerate() {
        let _ = writeln!(out, "    {}{}", poly(p), if m < 2 { "," } else { "" });
    }
    let _ = writeln!(out, "}};");
    let _ = writeln!(out, "static const double ACCELCAL_S_POLY[3][3][4] = {{");
    for (m, row) in model.s.iter().enumerate() {
        let cells: Vec<String> = row.iter().map(poly).collect();
        let _ = writeln!(
            out,
            "    {{ {} }}{}",
            cells.join(", "),
            if m < 2 { "," } else { "" }
        );
    }
    let _ = writeln!(out, "}};");
    let _ = writeln!(out, "#endif /* ACCELCAL_TRIAD_THERMAL_H */");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poly(coefficients: Vec<f64>, variances: Vec<f64>) -> Polynomial {
        let n = coefficients.len();
        Polynomial {
            reference_c: 20.0,
            degree: n - 1,
            std_uncertainties: variances.iter().map(|v| v.sqrt()).collect(),
            covariance: (0..n)
                .map(|i| {
                    (0..n)
                        .map(|j| if i == j { variances[i] } else { 0.0 })
                        .collect()
                })
                .collect(),
            coefficients,
            chi2: 0.0,
            dof: 3,
            inflation: 1.0,
            range_c: [-20.0, 60.0],
            selection: Vec::new(),
        }
    }

    /// `E` is the largest `|Δ|` at the range's ends or where `Δ' = 0`
    /// inside it, with `U` there; a constant drops nothing.
    #[test]
    fn the_effect_is_the_largest_change_over_the_range() {
        let p = poly(vec![9.8, 1.0, -0.01], vec![0.0, 1e-4, 1e-8]);
        let d = effect(&p, "S_xx".into());
        assert_eq!(d.at_c, -20.0);
        assert!((d.effect - 56.0).abs() < 1e-12, "{d:?}");
        // U = 2 √(x² · 1e-4 + x⁴ · 1e-8) at x = −40.
        let u = (1600.0f64 * 1e-4 + 2_560_000.0 * 1e-8).sqrt();
        assert!((d.expanded - 2.0 * u).abs() < 1e-12, "{d:?}");
        // Δ = −x + 0.025 x² has Δ' = 0 at x = 20 (40 °C), inside: a
        // candidate, though the ends are larger here (x = −40: 80).
        let p = poly(vec![0.0, -1.0, 0.025], vec![0.0, 0.0, 0.0]);
        assert!(candidates(&p).contains(&40.0));
        // Δ = x³ − 300 x on x in [−15, 5] (5 to 25 °C): Δ' = 0 at x = ±10,
        // only −10 inside, where Δ = 2000; the ends give −1125 and −1375.
        let mut p = poly(vec![0.0, -300.0, 0.0, 1.0], vec![0.0; 4]);
        p.range_c = [5.0, 25.0];
        let d = effect(&p, "S_yy".into());
        assert_eq!(d.at_c, 10.0, "{d:?}");
        assert!((d.effect - 2000.0).abs() < 1e-9, "{d:?}");
        // A constant drops nothing.
        let d = effect(&poly(vec![9.8], vec![1e-6]), "S_zz".into());
        assert_eq!((d.effect, d.expanded), (0.0, 0.0));
    }
}
