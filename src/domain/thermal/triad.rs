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

use accelcal_core::TermMap;
use accelcal_core::gravity_fit::{self, MIN_POSITIONS};
use accelcal_core::static_intervals::{self, Detector};
use accelcal_core::thermal::{Options, Point, Polynomial};
use accelcal_core::triad::{AXES, TriadRun, TriadTest};
use serde::{Deserialize, Serialize};

use super::super::field::{Invalid, Loc};
use super::super::triad::{
    FIXED_BY_CONVENTION, Form, GRAVITY_MAGNITUDE, KNOWN_ORIENTATIONS, Slot, TriadSubmission,
    detect_problem, row_terms,
};
use super::at::read;
use super::{ThermalParams, fitted, grouped, held, list, round, selection};

/// `known_orientations`: what a model stored before the method was
/// stated used.
fn known_orientations() -> String {
    KNOWN_ORIENTATIONS.to_owned()
}

/// One set point of a triad, calibrated and fused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
    /// Each axis's fused degrees of freedom by single-axis term (`k0` of
    /// `b_m`, `ki`, `kp`, `ko` of row `m` of `S`), as a single axis states
    /// them (an infinite ν left out): what a sensor type's decision takes
    /// `k` at. None in a model stored before they were kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes_dof: Option<[TermMap<f64>; 3]>,
}

/// A triad's temperature model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TriadThermalModel {
    /// The triad's id, when given.
    pub sensor_id: Option<String>,
    /// The outputs' unit.
    pub unit: String,
    /// How each set point was calibrated: `known_orientations` (runs at
    /// known orientations), or `gravity_magnitude` (static positions, the
    /// frame fixed by the sensor's x axis and xy-plane: `S_xy`, `S_xz`,
    /// `S_yz` are zero by convention, not measured, and their polynomials
    /// exactly zero).
    #[serde(default = "known_orientations")]
    pub method: String,
    /// The tolerance the runs were grouped with, K.
    pub tolerance_k: f64,
    /// How each degree was chosen (`backward`, `forward`), or `fixed`.
    pub selection: String,
    /// The parameters it was fitted with, as asked (what a reprocessing
    /// of a stored model fits with again).
    #[serde(default)]
    pub fitted_with: ThermalParams,
    /// The set points, coolest first.
    pub set_points: Vec<TriadSetPoint>,
    /// Each element of `b`'s polynomial, its `a_d` in the outputs' unit
    /// per K^d.
    pub b: [Polynomial; 3],
    /// Each element of `S`'s polynomial, row by row, its `a_d` in outputs
    /// per g per K^d.
    #[serde(rename = "S")]
    pub s: [[Polynomial; 3]; 3],
    /// The standard uncertainty of the named thermometer's reading, K: an
    /// element read at a temperature adds `u_T · |de/dT|` to its budget
    /// ([`TriadThermalModel::at`]). None when no thermometer was named.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermometer_std_c: Option<f64>,
}

/// The temperature model of the triad `sub` (module doc), its runs (or
/// static positions) grouped within `tolerance_k` and each polynomial
/// fitted with `options`.
pub fn triad_model(
    sub: &TriadSubmission,
    tolerance_k: f64,
    options: &Options,
) -> Result<TriadThermalModel, Invalid> {
    let (method, set_points, at, options) = match &sub.form {
        Form::Known {
            positions,
            runs,
            batches,
            second_order,
            temperatures_c,
            position_temperatures_c,
        } => {
            if *second_order {
                return Err(Invalid::one(
                    "/second_order",
                    "second-order terms are not modelled over temperature: omit it",
                ));
            }
            held(position_temperatures_c, tolerance_k)?;
            let (groups, at, options) = grouped(temperatures_c.as_deref(), tolerance_k, options)?;
            let set_points = known(positions, runs, *batches, groups)?;
            (KNOWN_ORIENTATIONS, set_points, at, options)
        }
        Form::Unknown {
            means,
            temperatures_c,
        } => {
            let Some(temperatures_c) = temperatures_c else {
                return Err(required(
                    "/static_temperatures_c",
                    "static positions",
                    "position",
                ));
            };
            let (groups, at, options) = grouped(Some(temperatures_c), tolerance_k, options)?;
            (GRAVITY_MAGNITUDE, unknown(means, groups)?, at, options)
        }
        Form::Recording {
            rate_hz,
            samples,
            detector,
            temperatures_c,
        } => {
            let Some(temperatures_c) = temperatures_c else {
                return Err(required(
                    "/recording/temperature_c",
                    "a recording",
                    "sample",
                ));
            };
            let (means, at_interval) =
                intervals(*rate_hz, samples, detector, temperatures_c, tolerance_k)?;
            let (groups, at, options) = grouped(Some(&at_interval), tolerance_k, options)?;
            (GRAVITY_MAGNITUDE, unknown(&means, groups)?, at, options)
        }
    };
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
    let by_convention = method == GRAVITY_MAGNITUDE;
    for (m, row) in AXES.iter().enumerate() {
        b.push(fit(format!("b_{row}"), &|p| (p.b[m], p.b_std_errors[m]))?);
        for (n, column) in AXES.iter().enumerate() {
            if by_convention && FIXED_BY_CONVENTION.contains(&(m, n)) {
                s.push(zero(&set_points, &at));
                continue;
            }
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
        method: method.to_owned(),
        tolerance_k,
        selection: selection(&options),
        fitted_with: ThermalParams::default(),
        set_points,
        b: b.try_into().expect("three"),
        s,
        thermometer_std_c: None,
    })
}

/// The refusal of a model from `what` (static positions, a recording)
/// without the temperatures at `pointer`, one per `each`.
fn required(pointer: &str, what: &str, each: &str) -> Invalid {
    Invalid::one(
        pointer,
        format!(
            "is required: a triad's temperature model from {what} needs each {each}'s \
             temperature"
        ),
    )
}

/// Each set point of `groups` (runs at known `positions`) calibrated and
/// fused as a triad is, with `batches` (fewer where a set point has fewer
/// than two runs a batch).
fn known(
    positions: &[[f64; 3]],
    runs: &[TriadRun],
    batches: usize,
    groups: Vec<accelcal_core::thermal::SetPoint>,
) -> Result<Vec<TriadSetPoint>, Invalid> {
    let mut set_points = Vec::with_capacity(groups.len());
    for g in groups {
        let of_group: Vec<TriadRun> = g.runs.iter().map(|&j| runs[j].clone()).collect();
        let used = batches.min((of_group.len() / 2).max(1));
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
            // An infinite ν (a batch variance of zero) is stated as none.
            axes_dof: Some(cal.axes.each_ref().map(|a| {
                TermMap(
                    a.fused
                        .dof
                        .iter()
                        .filter(|(_, d)| d.is_finite())
                        .map(|(t, d)| (t, *d))
                        .collect(),
                )
            })),
        });
    }
    Ok(set_points)
}

/// Each set point of `groups` (static positions whose mean outputs are
/// `means`) fitted from the gravity magnitude on its own, as
/// `POST /v1/identify/triad` fits its positions alone: at least
/// [`MIN_POSITIONS`]` + 1` positions each, so that every element has a
/// standard error to weight its polynomial with; every element's degrees of
/// freedom the fit's `n − 9`.
fn unknown(
    means: &[[f64; 3]],
    groups: Vec<accelcal_core::thermal::SetPoint>,
) -> Result<Vec<TriadSetPoint>, Invalid> {
    let mut set_points = Vec::with_capacity(groups.len());
    for g in groups {
        let at = format!("/static_positions/{}", g.runs[0]);
        let here = || format!("the set point at {} °C", round(g.temperature_c));
        if g.runs.len() <= MIN_POSITIONS {
            return Err(Invalid::one(
                at,
                format!(
                    "{} holds {} static positions (positions {}): at least {} are needed for \
                     b and S with standard errors at one temperature",
                    here(),
                    g.runs.len(),
                    list(&g.runs),
                    MIN_POSITIONS + 1
                ),
            ));
        }
        let of_group: Vec<[f64; 3]> = g.runs.iter().map(|&j| means[j]).collect();
        let f = gravity_fit::fit(&of_group)
            .map_err(|e| Invalid::one(at.clone(), format!("{}: {e}", here())))?;
        let (Some(b_std), Some(s_std)) = (f.bias_std, f.s_std) else {
            return Err(Invalid::one(at, format!("{}: no standard errors", here())));
        };
        let dof = f.degrees_of_freedom as f64;
        let axis_dof = |m: usize| {
            TermMap(
                row_terms(m)
                    .into_iter()
                    .filter(|(_, slot)| match slot {
                        Slot::B => true,
                        Slot::S(k) => !FIXED_BY_CONVENTION.contains(&(m, *k)),
                        Slot::S2 => false,
                    })
                    .map(|(t, _)| (t, dof))
                    .collect(),
            )
        };
        set_points.push(TriadSetPoint {
            temperature_c: g.temperature_c,
            runs: g.runs,
            batches: 1,
            b: f.bias,
            b_std_errors: b_std,
            s: f.s,
            s_std_errors: s_std,
            axes_dof: Some(std::array::from_fn(axis_dof)),
        });
    }
    Ok(set_points)
}

/// A recording's static intervals found as a triad's are
/// ([`static_intervals::detect`]): each used interval's mean outputs, and
/// its samples' mean temperature — refused where they span more than
/// `tolerance_k` (a position must hold its set point).
pub(super) fn intervals(
    rate_hz: f64,
    samples: &[[f64; 3]],
    detector: &Detector,
    temperatures_c: &[f64],
    tolerance_k: f64,
) -> Result<(Vec<[f64; 3]>, Vec<f64>), Invalid> {
    let at = Loc::Root.key("recording");
    let found = static_intervals::detect(rate_hz, samples, detector)
        .map_err(|e| detect_problem(&at, &e))?;
    let mut means = Vec::new();
    let mut temperatures = Vec::new();
    for i in found.intervals.iter().filter(|i| i.rejected.is_none()) {
        let ts = &temperatures_c[i.start..i.end];
        let lo = ts.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = ts.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if hi - lo > tolerance_k {
            return Err(Invalid::one(
                "/recording/temperature_c",
                format!(
                    "drifted {:.3} K during the static interval from {:.1} s to {:.1} s ({lo} \
                     to {hi} °C), more than the set points' tolerance of {tolerance_k} K: hold \
                     each orientation while the chamber holds its set point (or widen \
                     tolerance_k)",
                    hi - lo,
                    i.start as f64 / rate_hz,
                    i.end as f64 / rate_hz
                ),
            ));
        }
        means.push(i.mean);
        temperatures.push(ts.iter().sum::<f64>() / ts.len() as f64);
    }
    Ok((means, temperatures))
}

/// The polynomial of an element zero by the frame convention of a fit from
/// the gravity magnitude: `0` of degree 0, exactly, on the set points'
/// range about `T_ref` (not fitted: it is not measured).
fn zero(set_points: &[TriadSetPoint], at: &[f64]) -> Polynomial {
    let lo = set_points.first().map_or(f64::NAN, |s| s.temperature_c);
    let hi = set_points.last().map_or(f64::NAN, |s| s.temperature_c);
    Polynomial {
        reference_c: at.first().copied().unwrap_or(f64::NAN),
        degree: 0,
        coefficients: vec![0.0],
        std_uncertainties: vec![0.0],
        covariance: vec![vec![0.0]],
        chi2: 0.0,
        dof: set_points.len().saturating_sub(1),
        inflation: 1.0,
        range_c: [lo, hi],
        selection: Vec::new(),
    }
}

/// A triad's model read at one temperature: every element of `b` and `S`
/// with its standard uncertainty `√(vᵀ C v)` through its polynomial's
/// covariance, and how far outside the valid range.
#[derive(Clone, Debug, PartialEq)]
pub struct TriadAt {
    /// `b(T)`.
    pub b: [f64; 3],
    /// Their standard uncertainties.
    pub b_std_errors: [f64; 3],
    /// `S(T)`, rows by axis.
    pub s: [[f64; 3]; 3],
    /// Their standard uncertainties.
    pub s_std_errors: [[f64; 3]; 3],
    /// How far outside the valid range, K (0 within).
    pub outside_k: f64,
}

impl TriadThermalModel {
    /// `T_ref`, °C (every element's: the set points are one).
    pub fn reference_c(&self) -> f64 {
        self.b[0].reference_c
    }

    /// The valid range `[T_min, T_max]`, °C: the set points' span.
    pub fn range_c(&self) -> [f64; 2] {
        self.b[0].range_c
    }

    /// Every element at `temperature_c`, the thermometer's term included
    /// ([`super::at::read`]).
    pub fn at(&self, temperature_c: f64) -> TriadAt {
        let read = |p: &Polynomial| read(p, temperature_c, self.thermometer_std_c);
        let b = self.b.each_ref().map(read);
        let s = self.s.each_ref().map(|row| row.each_ref().map(read));
        TriadAt {
            b: b.map(|(v, _)| v),
            b_std_errors: b.map(|(_, u)| u),
            s: s.map(|row| row.map(|(v, _)| v)),
            s_std_errors: s.map(|row| row.map(|(_, u)| u)),
            outside_k: self.b[0].outside_k(temperature_c),
        }
    }

    /// Every polynomial, named (`b_x`, `S_xy`), `b` first and `S` by rows.
    pub fn polynomials(&self) -> impl Iterator<Item = (String, &Polynomial)> {
        let b = AXES.iter().zip(&self.b).map(|(m, p)| (format!("b_{m}"), p));
        let s = AXES.iter().zip(&self.s).flat_map(|(m, row)| {
            AXES.iter()
                .zip(row)
                .map(move |(n, p)| (format!("S_{m}{n}"), p))
        });
        b.chain(s)
    }

    /// Every number it holds, named: what must be finite to be stored.
    pub fn numbers(&self) -> impl Iterator<Item = (String, f64)> + '_ {
        let set_points = self.set_points.iter().enumerate().flat_map(|(k, p)| {
            let values = std::iter::once(p.temperature_c)
                .chain(p.b)
                .chain(p.b_std_errors)
                .chain(p.s.into_iter().flatten())
                .chain(p.s_std_errors.into_iter().flatten());
            values.map(move |v| (format!("set_points[{k}]"), v))
        });
        let polynomials = self.polynomials().flat_map(|(name, p)| {
            p.coefficients
                .iter()
                .chain(&p.std_uncertainties)
                .chain(p.covariance.iter().flatten())
                .chain(&p.range_c)
                .chain([&p.reference_c, &p.chi2, &p.inflation])
                .map(move |v| (name.clone(), *v))
        });
        set_points
            .chain(polynomials)
            .chain([("tolerance_k".to_owned(), self.tolerance_k)])
            .chain(
                self.thermometer_std_c
                    .map(|u| ("thermometer_std_c".to_owned(), u)),
            )
    }
}
