//! A triad's `b` and `S` over temperature (issue 45 item 1, triads): the
//! runs of a triad with known orientations, each with its temperature,
//! grouped into set points ([`accelcal_core::thermal::set_points`]); each
//! set point calibrated and fused exactly as a triad is
//! ([`accelcal_core::triad::TriadTest`]); and every element of `b` and `S`
//! given its polynomial `e(T) = Σ a_d (T − T_ref)^d`, fitted to the set
//! points' fused elements weighted by `1 / se²`
//! ([`accelcal_core::thermal::fit`], the single axis's contract). The
//! elements share the set points, so their `T_ref` and range are one; each
//! has its own degree.

use accelcal_core::thermal::{Options, Point, Polynomial};
use accelcal_core::triad::{AXES, TriadRun, TriadTest};
use serde::Serialize;

use super::super::field::Invalid;
use super::super::triad::{Form, TriadSubmission};
use super::{fitted, grouped, list, round, selection};

/// One set point of a triad, calibrated and fused.
#[derive(Clone, Debug, Serialize)]
pub struct TriadSetPoint {
    /// The mean of its runs' temperatures, °C.
    pub temperature_c: f64,
    /// Its runs (indices into the submission's).
    pub runs: Vec<usize>,
    /// The fusion batches used: the submission's, fewer when the set point
    /// has fewer than two runs a batch.
    pub batches: usize,
    /// Its fused bias `b`, in the outputs' unit.
    pub b: [f64; 3],
    /// Their standard errors.
    pub b_std_errors: [f64; 3],
    /// Its fused `S` (outputs per g), row by row.
    #[serde(rename = "S")]
    pub s: [[f64; 3]; 3],
    /// Their standard errors.
    #[serde(rename = "S_std_errors")]
    pub s_std_errors: [[f64; 3]; 3],
}

/// A triad's temperature model.
#[derive(Clone, Debug, Serialize)]
pub struct TriadThermalModel {
    /// The triad's id, when given.
    pub sensor_id: Option<String>,
    /// The outputs' unit.
    pub unit: String,
    /// The tolerance the runs were grouped with, K.
    pub tolerance_k: f64,
    /// How each degree was chosen (`backward`, `forward`), or `fixed`.
    pub selection: String,
    /// The set points, coolest first.
    pub set_points: Vec<TriadSetPoint>,
    /// Each element of `b`'s polynomial, its `a_d` in the outputs' unit
    /// per K^d.
    pub b: [Polynomial; 3],
    /// Each element of `S`'s polynomial, row by row, its `a_d` in outputs
    /// per g per K^d.
    #[serde(rename = "S")]
    pub s: [[Polynomial; 3]; 3],
}

/// The temperature model of the triad `sub` (module doc), its runs
/// grouped within `tolerance_k` and each polynomial fitted with `options`.
pub fn triad_model(
    sub: &TriadSubmission,
    tolerance_k: f64,
    options: &Options,
) -> Result<TriadThermalModel, Invalid> {
    let Form::Known {
        positions,
        runs,
        batches,
        second_order,
        temperatures_c,
    } = &sub.form
    else {
        return Err(Invalid::one(
            "/orientations",
            "is required: a triad's temperature model is identified from known orientations \
             (`orientations` and `runs`, each run with its `temperature_c`)",
        ));
    };
    if *second_order {
        return Err(Invalid::one(
            "/second_order",
            "second-order terms are not modelled over temperature: omit it",
        ));
    }
    let (groups, at, options) = grouped(temperatures_c.as_deref(), tolerance_k, options)?;
    let mut set_points = Vec::with_capacity(groups.len());
    for g in groups {
        let of_group: Vec<TriadRun> = g.runs.iter().map(|&j| runs[j].clone()).collect();
        let used = (*batches).min((of_group.len() / 2).max(1));
        let cal = TriadTest::new(positions, &of_group)
            .and_then(|t| t.calibrate(used))
            .map_err(|e| {
                Invalid::one(
                    format!("/runs/{}", g.runs[0]),
                    format!(
                        "the set point at {} °C (runs {}) cannot be calibrated on its own: {e}",
                        round(g.temperature_c),
                        list(&g.runs)
                    ),
                )
            })?;
        set_points.push(TriadSetPoint {
            temperature_c: g.temperature_c,
            runs: g.runs,
            batches: used,
            b: cal.fused.bias,
            b_std_errors: cal.std_errors.bias,
            s: cal.fused.matrix,
            s_std_errors: cal.std_errors.matrix,
        });
    }
    let fit = |name: String, element: &dyn Fn(&TriadSetPoint) -> (f64, f64)| {
        let points: Vec<Point> = set_points
            .iter()
            .map(|s| {
                let (value, std_uncertainty) = element(s);
                Point {
                    temperature_c: s.temperature_c,
                    value,
                    std_uncertainty,
                }
            })
            .collect();
        fitted(&name, &points, &options, &at)
    };
    let mut b = Vec::with_capacity(3);
    let mut s = Vec::with_capacity(9);
    for (m, row) in AXES.iter().enumerate() {
        b.push(fit(format!("b_{row}"), &|p| (p.b[m], p.b_std_errors[m]))?);
        for (n, column) in AXES.iter().enumerate() {
            s.push(fit(format!("S_{row}{column}"), &|p| {
                (p.s[m][n], p.s_std_errors[m][n])
            })?);
        }
    }
    let mut s = s.into_iter();
    let mut row = || -> [Polynomial; 3] { std::array::from_fn(|_| s.next().expect("nine")) };
    let s = [row(), row(), row()];
    Ok(TriadThermalModel {
        sensor_id: sub.sensor_id.clone(),
        unit: sub.unit.clone(),
        tolerance_k,
        selection: selection(&options),
        set_points,
        b: b.try_into().expect("three"),
        s,
    })
}
