//! Coefficients over temperature (issue 45): one coefficient's estimates at
//! several temperature set points fitted by a polynomial about a reference
//! temperature, its degree chosen by forward selection, its covariance
//! inflated by the Birge ratio, evaluated with its standard uncertainty.
//!
//! **Set points.** Runs sorted by temperature; a run joins the current set
//! point while it lies within `tolerance_k` of that set point's coolest run
//! (so no set point spans more than the tolerance), else it opens the next;
//! a set point's temperature is the mean of its runs' ([`set_points`]).
//!
//! **The model** of a coefficient `c` at temperature `T` (°C), about the
//! reference `T_ref`:
//!
//! ```text
//! c(T) = Σ_{d=0..D} a_d (T − T_ref)^d
//! ```
//!
//! fitted to the set points' estimates `c_s ± u_s` (s = 1..N) by weighted
//! least squares, `X_sd = (T_s − T_ref)^d`, `W = diag(1 / u_s²)`:
//!
//! ```text
//! a   = (XᵀWX)⁻¹ XᵀW c
//! χ²  = Σ_s (c_s − (X a)_s)² / u_s²,       ν = N − D − 1
//! C_a = (XᵀWX)⁻¹ · max(1, χ²/ν)            (the Birge ratio² when the points
//!                                            scatter more than their u_s say)
//! ```
//!
//! solved through the SVD of `W^½ X` (never the normal equations). At a
//! temperature `T`, with `v_d = (T − T_ref)^d`: `c(T) = vᵀa`, its standard
//! uncertainty `√(vᵀ C_a v)`, and its slope `dc/dT = Σ_{d≥1} d·a_d (T − T_ref)^{d−1}`.
//!
//! **The degree**, unless one is asked for, by **backward elimination**
//! ([`Selection::Backward`], the default): from the highest degree the set
//! points allow, `D = min(3, N − 2)` (lowered while its design is past the
//! condition limit), the top degree is dropped while its partial F
//!
//! ```text
//! F = (χ²_{D−1} − χ²_D) / (χ²_D / (N − D − 1))
//! ```
//!
//! does not exceed the upper `alpha` point (1 %) of `F(1, N − D − 1)`.
//! The issue's rule, **forward selection** ([`Selection::Forward`]) — from
//! `D = 0`, add degree `D + 1` while `F = (χ²_D − χ²_{D+1}) / (χ²_{D+1} /
//! (N − D − 2))` exceeds the upper 1 % point of `F(1, N − D − 2)`, up to
//! [`MAX_DEGREE`] and `D ≤ N − 2` — is kept for comparison, and not the
//! default: it judges each added degree against a residual that still holds
//! every higher one, so it stops short of a strongly curved model. On seven
//! set points of a planted cubic (`core/tests/data/thermal.py`, noise at
//! `u`) it stops at degree 0 with `χ²` = 3.0·10⁶ left in the residual, and
//! on a cubic with a small quadratic at degree 1; backward elimination picks
//! 3 on both, and the planted degree on every other case. The price: on a
//! true degree below the highest, backward elimination makes one test per
//! degree above it, each at `alpha`, so it keeps a spurious degree a little
//! more often — for a true line on five set points 1 − 0.99² ≈ 2 % against
//! forward selection's 1 % (2 000 simulated lines: 39 and 23,
//! `core/tests/suite/thermal.rs`). An extra degree costs uncertainty, never
//! a wrong value within the range; a missing one leaves a systematic error.
//!
//! **Refusals** keep the polynomial sane ([`ThermalError`]): fewer distinct
//! set points than `D + 2` (so `ν ≥ 1`), a span of set points below the
//! minimum (default [`MIN_SPAN_K`]), and a design whose condition number —
//! of `X` with each column scaled to unit length, so that it measures the
//! temperatures' spread and not the units — exceeds the limit (default
//! [`MAX_CONDITION`]). The valid range is the set points' span.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::ftest::FTest;

/// The highest degree fitted.
pub const MAX_DEGREE: usize = 3;
/// The default tolerance within which runs form one set point, K.
pub const TOLERANCE_K: f64 = 0.5;
/// The default smallest span of set points, K.
pub const MIN_SPAN_K: f64 = 10.0;
/// The default largest condition number of the (column-scaled) design. A
/// design of condition number κ can amplify the set points' relative errors
/// up to κ-fold in the polynomial's coefficients; 100 admits every spread a
/// chamber schedule uses (five set points evenly over 80 K: 2.8 at degree
/// 2, 5.8 at degree 3) and refuses a cubic through a cluster (four set
/// points within 2 K and a fifth 13 K away: 303).
pub const MAX_CONDITION: f64 = 100.0;
/// The level of the forward selection's F tests.
pub const ALPHA: f64 = 0.01;

/// One set point: its temperature and the runs (indices into the caller's
/// list) made at it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SetPoint {
    /// The mean of its runs' temperatures, °C.
    pub temperature_c: f64,
    /// Its runs, in the caller's order.
    pub runs: Vec<usize>,
}

/// Groups runs made at `temperatures_c` into set points, coolest first
/// (module doc); `tolerance_k` must be finite and not negative.
pub fn set_points(temperatures_c: &[f64], tolerance_k: f64) -> Vec<SetPoint> {
    let mut order: Vec<usize> = (0..temperatures_c.len()).collect();
    order.sort_by(|&a, &b| temperatures_c[a].total_cmp(&temperatures_c[b]));
    let mut out: Vec<(f64, Vec<usize>)> = Vec::new();
    for j in order {
        let t = temperatures_c[j];
        match out.last_mut() {
            Some((coolest, runs)) if t - *coolest <= tolerance_k => runs.push(j),
            _ => out.push((t, vec![j])),
        }
    }
    out.into_iter()
        .map(|(_, mut runs)| {
            let mean = runs.iter().map(|&j| temperatures_c[j]).sum::<f64>() / runs.len() as f64;
            runs.sort_unstable();
            SetPoint {
                temperature_c: mean,
                runs,
            }
        })
        .collect()
}

/// The default reference temperature: the mean of the set points'
/// temperatures, rounded to 0.1 K (halves away from zero: 27.25 → 27.3).
pub fn reference(temperatures_c: &[f64]) -> f64 {
    let mean = temperatures_c.iter().sum::<f64>() / temperatures_c.len().max(1) as f64;
    (mean * 10.0).round() / 10.0
}

/// One set point's estimate of a coefficient.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Point {
    /// The set point's temperature, °C.
    pub temperature_c: f64,
    /// The coefficient's estimate there.
    pub value: f64,
    /// Its statistical standard uncertainty (the weight is `1 / u²`).
    pub std_uncertainty: f64,
}

/// Why no polynomial is fitted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ThermalError {
    /// Fewer distinct set points than the degree needs.
    #[error(
        "{distinct} distinct temperature set point(s): a polynomial of degree {degree} needs at least {needed}"
    )]
    TooFewSetPoints {
        /// Set points given.
        distinct: usize,
        /// The degree asked for (0 when selecting).
        degree: usize,
        /// `degree + 2`.
        needed: usize,
    },
    /// The set points span too little.
    #[error(
        "the set points span {span_k} K, less than the {min_span_k} K a temperature model needs"
    )]
    SpanTooSmall {
        /// `T_max − T_min`.
        span_k: f64,
        /// The minimum.
        min_span_k: f64,
    },
    /// The design is ill-conditioned at that degree.
    #[error(
        "the set points' temperatures make a degree-{degree} design with condition number {condition:.0}, past the limit {limit}"
    )]
    IllConditioned {
        /// The degree.
        degree: usize,
        /// Its condition number.
        condition: f64,
        /// The limit.
        limit: f64,
    },
    /// A degree above [`MAX_DEGREE`] was asked for.
    #[error("degree {0} asked for: at most {MAX_DEGREE}")]
    DegreeTooHigh(usize),
    /// The fit's numbers are not finite (weights at the edges of `f64`).
    #[error(
        "the set points' estimates and standard errors are too far apart in scale to weight (the fit overflows)"
    )]
    NotFinite,
    /// A point's value or uncertainty is not usable as a weight.
    #[error(
        "the set point at {temperature_c} °C has no positive, finite standard uncertainty, so it cannot be weighted"
    )]
    Unweighted {
        /// Its temperature.
        temperature_c: f64,
    },
}

/// How the degree is chosen when none is asked for (module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Selection {
    /// Down from the highest degree the set points allow (the default).
    #[default]
    Backward,
    /// Up from degree 0 (the issue's rule).
    Forward,
}

/// How a coefficient's polynomial is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Options {
    /// `T_ref`, °C; `None`: [`reference`](fn@reference) of the set points.
    pub reference_c: Option<f64>,
    /// The degree; `None`: chosen by `selection`.
    pub degree: Option<usize>,
    /// How the degree is chosen when none is asked for.
    pub selection: Selection,
    /// The smallest span of set points, K.
    pub min_span_k: f64,
    /// The largest condition number of the design.
    pub max_condition: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            reference_c: None,
            degree: None,
            selection: Selection::Backward,
            min_span_k: MIN_SPAN_K,
            max_condition: MAX_CONDITION,
        }
    }
}

/// A coefficient's fitted polynomial.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Polynomial {
    /// `T_ref`, °C.
    pub reference_c: f64,
    /// `D`.
    pub degree: usize,
    /// `a_0 … a_D`, in the coefficient's unit per K^d.
    pub coefficients: Vec<f64>,
    /// Their standard uncertainties, `√diag(C_a)`.
    pub std_uncertainties: Vec<f64>,
    /// `C_a`, row by row.
    pub covariance: Vec<Vec<f64>>,
    /// `χ²` of the fit.
    pub chi2: f64,
    /// `ν = N − D − 1`.
    pub dof: usize,
    /// `max(1, χ²/ν)`, the factor `(XᵀWX)⁻¹` was inflated by.
    pub inflation: f64,
    /// The valid range `[T_min, T_max]`, °C: the set points' span.
    pub range_c: [f64; 2],
    /// The selection's partial F tests in the order made (empty when the
    /// degree was asked for).
    pub selection: Vec<FTest>,
}

/// One weighted fit of degree `degree`: `(a, (XᵀWX)⁻¹, χ²)`.
fn weighted(points: &[Point], reference_c: f64, degree: usize) -> (Vec<f64>, DMatrix<f64>, f64) {
    let n = points.len();
    let a = DMatrix::from_fn(n, degree + 1, |s, d| {
        (points[s].temperature_c - reference_c).powi(d as i32) / points[s].std_uncertainty
    });
    let b = DVector::from_fn(n, |s, _| points[s].value / points[s].std_uncertainty);
    if !a.iter().all(|x| x.is_finite()) {
        // Overflowed weights: no factorisation of infinities (the caller
        // refuses the non-finite fit; a non-finite `b` alone reaches it
        // through the solution).
        let nan = DMatrix::from_element(degree + 1, degree + 1, f64::NAN);
        return (vec![f64::NAN; degree + 1], nan, f64::NAN);
    }
    let svd = a.clone().svd(true, true);
    let (u, v_t) = (
        svd.u.as_ref().expect("computed"),
        svd.v_t.as_ref().expect("computed"),
    );
    let s = &svd.singular_values;
    // a = V Σ⁻¹ Uᵀ b; (AᵀA)⁻¹ = V Σ⁻² Vᵀ (full column rank: the condition
    // number was checked, so every σ is positive).
    let utb = u.transpose() * &b;
    let scaled = DVector::from_fn(degree + 1, |k, _| utb[k] / s[k]);
    let coef = v_t.transpose() * scaled;
    let inv_s2 = DMatrix::from_diagonal(&s.map(|x| 1.0 / (x * x)));
    let cov = v_t.transpose() * inv_s2 * v_t;
    let chi2 = (a * &coef - b).norm_squared();
    (coef.iter().copied().collect(), cov, chi2)
}

/// The condition number of the design of `temperatures_c` about
/// `reference_c` at `degree`, its columns scaled to unit length.
pub fn condition(temperatures_c: &[f64], reference_c: f64, degree: usize) -> f64 {
    let mut x = DMatrix::from_fn(temperatures_c.len(), degree + 1, |s, d| {
        (temperatures_c[s] - reference_c).powi(d as i32)
    });
    for mut column in x.column_iter_mut() {
        let norm = column.norm();
        if norm == 0.0 {
            // Every temperature at the reference: a zero column, singular.
            return f64::INFINITY;
        }
        column /= norm;
    }
    let s = x.singular_values();
    // A zero singular value gives +∞.
    s.max() / s.min()
}

/// Checks the set points' temperatures for a polynomial of `degree`
/// (`None`: the selection, which needs two) about `reference_c`.
pub fn check(
    temperatures_c: &[f64],
    reference_c: f64,
    degree: Option<usize>,
    options: &Options,
) -> Result<(), ThermalError> {
    let d = degree.unwrap_or(0);
    if d > MAX_DEGREE {
        return Err(ThermalError::DegreeTooHigh(d));
    }
    let mut distinct = temperatures_c.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() < d + 2 {
        return Err(ThermalError::TooFewSetPoints {
            distinct: distinct.len(),
            degree: d,
            needed: d + 2,
        });
    }
    let span = distinct[distinct.len() - 1] - distinct[0];
    if span < options.min_span_k {
        return Err(ThermalError::SpanTooSmall {
            span_k: span,
            min_span_k: options.min_span_k,
        });
    }
    if let Some(d) = degree {
        conditioned(temperatures_c, reference_c, d, options)?;
    }
    Ok(())
}

/// Refuses a design past the condition limit.
fn conditioned(
    temperatures_c: &[f64],
    reference_c: f64,
    degree: usize,
    options: &Options,
) -> Result<(), ThermalError> {
    let condition = condition(temperatures_c, reference_c, degree);
    if condition > options.max_condition {
        return Err(ThermalError::IllConditioned {
            degree,
            condition,
            limit: options.max_condition,
        });
    }
    Ok(())
}

/// A coefficient's polynomial over its set points' estimates `points`
/// (module doc): the degree asked for in `options`, or the selected one.
pub fn fit(points: &[Point], options: &Options) -> Result<Polynomial, ThermalError> {
    if let Some(p) = points.iter().find(|p| {
        !(p.std_uncertainty.is_finite() && p.std_uncertainty > 0.0 && p.value.is_finite())
    }) {
        return Err(ThermalError::Unweighted {
            temperature_c: p.temperature_c,
        });
    }
    let temperatures: Vec<f64> = points.iter().map(|p| p.temperature_c).collect();
    let reference_c = options
        .reference_c
        .unwrap_or_else(|| reference(&temperatures));
    check(&temperatures, reference_c, options.degree, options)?;
    let n = points.len();
    let (degree, selection) = match (options.degree, options.selection) {
        (Some(d), _) => (d, Vec::new()),
        (None, Selection::Backward) => backward(points, &temperatures, reference_c, options),
        (None, Selection::Forward) => forward(points, &temperatures, reference_c, options),
    };
    conditioned(&temperatures, reference_c, degree, options)?;
    let (coefficients, cov, chi2) = weighted(points, reference_c, degree);
    let dof = n - degree - 1;
    let inflation = (chi2 / dof as f64).max(1.0);
    let covariance: Vec<Vec<f64>> = (0..=degree)
        .map(|i| (0..=degree).map(|j| cov[(i, j)] * inflation).collect())
        .collect();
    let std_uncertainties: Vec<f64> = (0..=degree).map(|d| covariance[d][d].sqrt()).collect();
    let mut numbers = std::iter::once(chi2)
        .chain(coefficients.iter().copied())
        .chain(std_uncertainties.iter().copied())
        .chain(covariance.iter().flatten().copied());
    if !numbers.all(f64::is_finite) {
        return Err(ThermalError::NotFinite);
    }
    let lo = temperatures.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = temperatures
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    Ok(Polynomial {
        reference_c,
        degree,
        coefficients,
        std_uncertainties,
        covariance,
        chi2,
        dof,
        inflation,
        range_c: [lo, hi],
        selection,
    })
}

/// The partial F test of degree `big` against `big − 1`, given their `χ²`
/// and the residual degrees of freedom `df2` of the larger; `None` when F
/// is infinite — the larger fits exactly where the smaller does not — so
/// the larger degree is significant beyond any level. (An undefined F, both
/// fits exact or a `χ²` overflowed, reads as 0: not significant.)
fn partial(small: f64, big: f64, df2: usize) -> Option<FTest> {
    FTest::new(((small - big) / (big / df2 as f64)).max(0.0), 1, df2, ALPHA)
}

/// Backward elimination (module doc): the degree and its tests.
fn backward(
    points: &[Point],
    temperatures: &[f64],
    reference_c: f64,
    options: &Options,
) -> (usize, Vec<FTest>) {
    let n = points.len();
    // The highest degree the set points allow whose design is within the
    // condition limit.
    let top = (1..=MAX_DEGREE.min(n.saturating_sub(2)))
        .rev()
        .find(|&d| conditioned(temperatures, reference_c, d, options).is_ok())
        .unwrap_or(0);
    let mut tests = Vec::new();
    for d in (1..=top).rev() {
        let big = weighted(points, reference_c, d).2;
        let small = weighted(points, reference_c, d - 1).2;
        let Some(test) = partial(small, big, n - d - 1) else {
            return (d, tests); // infinitely significant: kept
        };
        tests.push(test);
        if test.flagged() {
            return (d, tests);
        }
    }
    (0, tests)
}

/// Forward selection (module doc): the degree and its tests. Degree
/// `D + 1` is tried while `D + 1 ≤ N − 2`, so that its test has a degree of
/// freedom, and while its design is within the condition limit.
fn forward(
    points: &[Point],
    temperatures: &[f64],
    reference_c: f64,
    options: &Options,
) -> (usize, Vec<FTest>) {
    let n = points.len();
    let mut tests = Vec::new();
    let mut small = weighted(points, reference_c, 0).2;
    let mut degree = 0;
    for next in 1..=MAX_DEGREE.min(n.saturating_sub(2)) {
        if conditioned(temperatures, reference_c, next, options).is_err() {
            break;
        }
        let big = weighted(points, reference_c, next).2;
        if let Some(test) = partial(small, big, n - next - 1) {
            tests.push(test);
            if !test.flagged() {
                break;
            }
        }
        degree = next;
        small = big;
    }
    (degree, tests)
}

impl Polynomial {
    /// `v_d = (T − T_ref)^d`.
    fn powers(&self, temperature_c: f64) -> Vec<f64> {
        (0..=self.degree)
            .map(|d| (temperature_c - self.reference_c).powi(d as i32))
            .collect()
    }

    /// The coefficient at `temperature_c` and its standard uncertainty
    /// `√(vᵀ C_a v)`.
    pub fn at(&self, temperature_c: f64) -> (f64, f64) {
        let v = self.powers(temperature_c);
        let value = v.iter().zip(&self.coefficients).map(|(v, a)| v * a).sum();
        let var: f64 = (0..v.len())
            .flat_map(|i| (0..v.len()).map(move |j| (i, j)))
            .map(|(i, j)| v[i] * self.covariance[i][j] * v[j])
            .sum();
        (value, var.max(0.0).sqrt())
    }

    /// `dc/dT` at `temperature_c`.
    pub fn slope(&self, temperature_c: f64) -> f64 {
        let dt = temperature_c - self.reference_c;
        (1..=self.degree)
            .map(|d| d as f64 * self.coefficients[d] * dt.powi(d as i32 - 1))
            .sum()
    }

    /// How far `temperature_c` lies outside the valid range, K (0 within).
    pub fn outside_k(&self, temperature_c: f64) -> f64 {
        let [lo, hi] = self.range_c;
        (lo - temperature_c).max(temperature_c - hi).max(0.0)
    }
}

#[cfg(test)]
mod tests;
