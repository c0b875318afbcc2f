//! A triad's elements as the store keeps them beside the single-axis
//! columns (issue 30): `b`, `S`, `T` (and `S2`) with their standard errors
//! and expanded uncertainties, named element by element for stability and
//! reprocessing.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A triad calibration's elements (issue 30): `u = b + S g` with bias `b`
/// (the outputs' unit) and scale-and-misalignment `S` (the outputs' unit
/// per g, rows by axis), and `T = S⁻¹`, with the standard errors its
/// method gives. Row `m` of `S` is axis `m`'s `(ki, kp, ko)` and `b_m` its
/// `k0` in the single-axis model, which is why a triad's stored `model` is
/// `k0, ki, kp, ko`; its single-axis `coefficients` stay empty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TriadElements {
    /// `known_orientations` or `gravity_magnitude`.
    pub method: String,
    /// `b`.
    pub b: [f64; 3],
    /// Its standard errors (none with exactly nine static positions).
    pub b_std_errors: Option<[f64; 3]>,
    /// `S`, rows by axis.
    #[serde(rename = "S")]
    pub s: [[f64; 3]; 3],
    /// Its standard errors (known orientations).
    #[serde(rename = "S_std_errors")]
    pub s_std_errors: Option<[[f64; 3]; 3]>,
    /// `T = S⁻¹`.
    #[serde(rename = "T")]
    pub t: [[f64; 3]; 3],
    /// Its standard errors (unknown orientations, more than nine positions).
    #[serde(rename = "T_std_errors")]
    pub t_std_errors: Option<[[f64; 3]; 3]>,
    /// `b`'s expanded uncertainties (known orientations: each axis's `k0`
    /// budget).
    #[serde(default)]
    pub b_expanded: Option<[f64; 3]>,
    /// `S`'s expanded uncertainties (known orientations).
    #[serde(rename = "S_expanded", default)]
    pub s_expanded: Option<[[f64; 3]; 3]>,
    /// Each axis's second-order coefficient `S2_m` (its `kii`), when the
    /// model has them.
    #[serde(rename = "S2", default, skip_serializing_if = "Option::is_none")]
    pub s2: Option<[f64; 3]>,
    /// Their standard errors.
    #[serde(
        rename = "S2_std_errors",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub s2_std_errors: Option<[f64; 3]>,
    /// Their expanded uncertainties.
    #[serde(
        rename = "S2_expanded",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub s2_expanded: Option<[f64; 3]>,
}

impl TriadElements {
    /// The model `b`, `S` and `S2` describe (compensation inverts it).
    pub fn model(&self) -> accelcal_core::triad::Triad {
        accelcal_core::triad::Triad {
            bias: self.b,
            matrix: self.s,
            square: self.s2.unwrap_or([0.0; 3]),
        }
    }
}

/// The axes' names, in the order of `b`'s elements and `S`'s rows.
pub const AXES: [&str; 3] = ["x", "y", "z"];

/// One element of a stored triad ([`TriadElements::elements`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TriadElement {
    /// `b_x`, `S_xy`, `S2_z`, `T_zz`.
    pub name: String,
    /// Its value.
    pub value: f64,
    /// Its standard error, when the method gives one.
    pub std_error: Option<f64>,
    /// Its expanded uncertainty, when the method gives one.
    pub expanded: Option<f64>,
    /// Whether the calibration measured it: `T`, derived from `S`, is not,
    /// nor are the elements of `S` zero by a gravity-magnitude triad's
    /// frame convention.
    pub measured: bool,
}

impl TriadElements {
    /// The elements of `b`, `S`, `S2` and `T` by name (`b_x`, `S_xy`,
    /// `S2_z`, `T_zz`), each with its standard error and expanded
    /// uncertainty when the method gives them: what stability is judged on,
    /// element by element, and what the sensor's page charts (those
    /// [`TriadElement::measured`]).
    pub fn elements(&self) -> Vec<TriadElement> {
        let convention = self.method == crate::domain::triad::GRAVITY_MAGNITUDE;
        let mut out = Vec::with_capacity(24);
        let vector = |out: &mut Vec<TriadElement>,
                      name,
                      v: &[f64; 3],
                      se: Option<[f64; 3]>,
                      u: Option<[f64; 3]>| {
            for (m, axis) in AXES.iter().enumerate() {
                out.push(TriadElement {
                    name: format!("{name}_{axis}"),
                    value: v[m],
                    std_error: se.map(|e| e[m]),
                    expanded: u.map(|e| e[m]),
                    measured: true,
                });
            }
        };
        vector(&mut out, "b", &self.b, self.b_std_errors, self.b_expanded);
        for (name, matrix, se, u) in [
            ("S", &self.s, self.s_std_errors, self.s_expanded),
            ("T", &self.t, self.t_std_errors, None),
        ] {
            for (m, row) in AXES.iter().enumerate() {
                for (k, column) in AXES.iter().enumerate() {
                    out.push(TriadElement {
                        name: format!("{name}_{row}{column}"),
                        value: matrix[m][k],
                        std_error: se.map(|e| e[m][k]),
                        expanded: u.map(|e| e[m][k]),
                        measured: name == "S" && !(convention && k > m),
                    });
                }
            }
        }
        if let Some(s2) = &self.s2 {
            vector(&mut out, "S2", s2, self.s2_std_errors, self.s2_expanded);
        }
        out
    }

    /// Every stored number with its name (`b_x`, `S_xy`, `T_zz`,
    /// `b_x_std_error`, …): what must be finite, and what stability is
    /// judged on element by element.
    pub fn numbers(&self) -> Vec<(String, f64)> {
        let mut out = Vec::with_capacity(54);
        let vector = |out: &mut Vec<(String, f64)>, name: &str, suffix: &str, v: &[f64; 3]| {
            for (axis, x) in AXES.iter().zip(v) {
                out.push((format!("{name}_{axis}{suffix}"), *x));
            }
        };
        let matrix = |out: &mut Vec<(String, f64)>, name: &str, suffix: &str, m: &[[f64; 3]; 3]| {
            for (row, r) in AXES.iter().zip(m) {
                for (column, x) in AXES.iter().zip(r) {
                    out.push((format!("{name}_{row}{column}{suffix}"), *x));
                }
            }
        };
        vector(&mut out, "b", "", &self.b);
        matrix(&mut out, "S", "", &self.s);
        matrix(&mut out, "T", "", &self.t);
        for (suffix, v) in [
            ("", &self.s2),
            ("_std_error", &self.s2_std_errors),
            ("_expanded", &self.s2_expanded),
        ] {
            if let Some(v) = v {
                for (axis, x) in AXES.iter().zip(v) {
                    out.push((format!("S2_{axis}{suffix}"), *x));
                }
            }
        }
        const E: &str = "_std_error";
        if let Some(e) = &self.b_std_errors {
            vector(&mut out, "b", E, e);
        }
        if let Some(e) = &self.s_std_errors {
            matrix(&mut out, "S", E, e);
        }
        if let Some(e) = &self.t_std_errors {
            matrix(&mut out, "T", E, e);
        }
        const U: &str = "_expanded";
        if let Some(e) = &self.b_expanded {
            vector(&mut out, "b", U, e);
        }
        if let Some(e) = &self.s_expanded {
            matrix(&mut out, "S", U, e);
        }
        out
    }
}
