//! A calibration against the sensor's history: as found (how far the sensor
//! had drifted since its previous calibration) and stability over a series
//! of calibrations.
//!
//! **As found.** For each position `r`, with `ȳ_r` the mean of every sample
//! of every run at `r` (`Σ_j n_jr·ȳ_jr / Σ_j n_jr` when runs give their
//! readings as summaries) and `P` the previous calibration's fused model:
//!
//! ```text
//! error_output_r = ȳ_r − P(a_r),     error_g_r = error_output_r / ki_prev
//! ```
//!
//! — the error, in output units and in g, a control system still using the
//! previous coefficients would have made at that position.
//!
//! **Stability.** Over fused values `x_1 … x_n` of one coefficient, ordered by
//! `performed_at` `t_1 … t_n` (in years of 365.25 days):
//!
//! * `mean`, `std` (divisor `n − 1`; none for `n < 2`), `min`, `max`;
//! * drift by ordinary least squares of `x` on `t`: slope
//!   `b = Σ(t − t̄)(x − x̄) / Σ(t − t̄)²`, residual standard error
//!   `s = √(Σ r² / (n − 2))`, `SE(b) = s / √Σ(t − t̄)²`, `t = b / SE(b)` —
//!   none for `n < 3` (or when every `t` is the same); the t statistic is none
//!   when `SE(b) = 0` (a perfectly linear history);
//! * an individuals control chart: centre `x̄`, average moving range
//!   `MR̄ = Σ|x_i − x_{i−1}| / (n − 1)`, limits `x̄ ∓ 2.66·MR̄`, and the points
//!   outside them;
//! * the latest change `x_n − x_{n−1}`, its expanded uncertainty
//!   `k·√(se_n² + se_{n−1}²)` from the two fused standard errors, and whether
//!   the change exceeds it.

use serde::Serialize;

use crate::compensate::Compensator;
use crate::fusion::{mean, sample_std};
use crate::term::{Term, TermMap};
use crate::tumble::TumbleTest;

/// The error at one position with the previous coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PositionError {
    /// In the output's unit.
    pub error_output: f64,
    /// Referred to the input, in g (`error_output / ki_prev`).
    pub error_g: f64,
}

/// How far the sensor had drifted since its previous calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AsFound {
    /// One per position, in position order.
    pub positions: Vec<PositionError>,
    /// The largest `|error_g|`.
    pub max_abs_error_g: f64,
}

/// As found against `previous` fused coefficients; `None` when they have
/// no (or a zero) `ki` to refer errors to the input.
pub fn as_found(test: &TumbleTest, previous: &TermMap<f64>) -> Option<AsFound> {
    let ki = *previous.get(Term::Ki)?;
    if ki == 0.0 || !ki.is_finite() {
        return None;
    }
    let model = Compensator::new(previous).ok()?;
    let positions: Vec<PositionError> = test
        .positions()
        .iter()
        .enumerate()
        .map(|(r, p)| {
            let readings = test.runs().iter().map(|run| &run.readings[r]);
            let (sum, count) = readings.fold((0.0, 0.0), |(sum, count), reading| {
                let n = reading.count() as f64;
                (sum + n * reading.mean(), count + n)
            });
            let error_output = sum / count - model.output(&p.a);
            PositionError {
                error_output,
                error_g: error_output / ki,
            }
        })
        .collect();
    let max_abs_error_g = positions
        .iter()
        .map(|e| e.error_g.abs())
        .fold(0.0, f64::max);
    Some(AsFound {
        positions,
        max_abs_error_g,
    })
}

/// One calibration of a series.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Its id (reported for points outside the control limits).
    pub id: String,
    /// When it was performed, in years (any origin).
    pub t_years: f64,
    /// Fused coefficients.
    pub values: TermMap<f64>,
    /// Their fused standard errors.
    pub std_errors: TermMap<f64>,
}

/// An individuals (X–mR) control chart.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Control {
    /// The centre line, the mean.
    pub centre: f64,
    /// The average moving range; none for one point.
    pub moving_range_mean: Option<f64>,
    /// `centre − 2.66·MR̄`.
    pub lower: Option<f64>,
    /// `centre + 2.66·MR̄`.
    pub upper: Option<f64>,
    /// The calibrations outside the limits.
    pub out_of_control: Vec<String>,
}

/// The stability of one coefficient over the series.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TermStability {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation; none for fewer than two points.
    pub std: Option<f64>,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Least-squares slope, per year; none for fewer than three points.
    pub drift_per_year: Option<f64>,
    /// Its standard error.
    pub drift_std_error: Option<f64>,
    /// `drift_per_year / drift_std_error`; none when that is not finite.
    pub drift_t: Option<f64>,
    /// The individuals control chart.
    pub control: Control,
    /// `x_n − x_{n−1}`; none for one point.
    pub latest_change: Option<f64>,
    /// `k·√(se_n² + se_{n−1}²)`.
    pub latest_change_expanded: Option<f64>,
    /// `|latest_change| > latest_change_expanded`.
    pub latest_change_significant: Option<bool>,
}

/// Control-limit factor of an individuals chart (3 / d₂, d₂ = 1.128).
pub const CONTROL_FACTOR: f64 = 2.66;

/// Stability of every term present in all points (ordered by time, then by
/// id, by the caller), with coverage factor `k` for the latest change.
pub fn stability(points: &[Point], k: f64) -> TermMap<TermStability> {
    let Some(first) = points.first() else {
        return TermMap(Vec::new());
    };
    let terms: Vec<Term> = first
        .values
        .iter()
        .map(|(t, _)| t)
        .filter(|t| points.iter().all(|p| p.values.get(*t).is_some()))
        .collect();
    let t: Vec<f64> = points.iter().map(|p| p.t_years).collect();
    let ids: Vec<&str> = points.iter().map(|p| p.id.as_str()).collect();
    TermMap(
        terms
            .into_iter()
            .map(|term| {
                // Every point has the term (filtered above).
                let x: Vec<f64> = points
                    .iter()
                    .filter_map(|p| p.values.get(term).copied())
                    .collect();
                let se: Vec<Option<f64>> = points
                    .iter()
                    .map(|p| Some(p.std_errors.get(term).copied().unwrap_or(0.0)))
                    .collect();
                (term, quantity(&ids, &t, &x, &se, k))
            })
            .collect(),
    )
}

/// The stability of one quantity over time — the definitions above for a
/// series that is not a single-axis term (a triad's element): values `x`
/// at `t` (years, ordered), identified by `ids`, with standard errors `se`.
/// The latest change is judged only when both its points have a standard
/// error. The slices have one element per point.
pub fn quantity(ids: &[&str], t: &[f64], x: &[f64], se: &[Option<f64>], k: f64) -> TermStability {
    let n = x.len();
    let m = mean(x);
    let (drift_per_year, drift_std_error, drift_t) = drift(t, x);
    let moving_range_mean =
        (n >= 2).then(|| x.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>() / (n - 1) as f64);
    let lower = moving_range_mean.map(|mr| m - CONTROL_FACTOR * mr);
    let upper = moving_range_mean.map(|mr| m + CONTROL_FACTOR * mr);
    let out_of_control = match (lower, upper) {
        (Some(lo), Some(hi)) => ids
            .iter()
            .zip(x)
            .filter(|(_, v)| **v < lo || **v > hi)
            .map(|(id, _)| (*id).to_owned())
            .collect(),
        _ => Vec::new(),
    };
    let change = (n >= 2).then(|| x[n - 1] - x[n - 2]);
    let expanded = match (n >= 2).then(|| (se[n - 1], se[n - 2])) {
        Some((Some(a), Some(b))) => Some(k * (a.powi(2) + b.powi(2)).sqrt()),
        _ => None,
    };
    TermStability {
        mean: m,
        std: sample_std(x),
        min: x.iter().copied().fold(f64::INFINITY, f64::min),
        max: x.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        drift_per_year,
        drift_std_error,
        drift_t,
        control: Control {
            centre: m,
            moving_range_mean,
            lower,
            upper,
            out_of_control,
        },
        latest_change: change,
        latest_change_expanded: expanded,
        latest_change_significant: change.zip(expanded).map(|(c, e)| c.abs() > e),
    }
}

/// Ordinary least squares of `x` on `t`: slope, its standard error and t.
fn drift(t: &[f64], x: &[f64]) -> (Option<f64>, Option<f64>, Option<f64>) {
    let n = x.len();
    if n < 3 {
        return (None, None, None);
    }
    let (dt, dx) = (centred(t), centred(x));
    let stt: f64 = dt.iter().map(|d| d * d).sum();
    if stt == 0.0 {
        return (None, None, None);
    }
    let slope = dt.iter().zip(&dx).map(|(a, b)| a * b).sum::<f64>() / stt;
    let rss: f64 = dt
        .iter()
        .zip(&dx)
        .map(|(a, b)| (b - slope * a).powi(2))
        .sum();
    let se = (rss / (n - 2) as f64).sqrt() / stt.sqrt();
    let tstat = Some(slope / se).filter(|v| v.is_finite());
    (Some(slope), Some(se), tstat)
}

/// Each value less the mean of all.
pub(crate) fn centred(v: &[f64]) -> Vec<f64> {
    let m = mean(v);
    v.iter().map(|x| x - m).collect()
}

/// Seconds in a year of 365.25 days.
pub const SECONDS_PER_YEAR: f64 = 365.25 * 86_400.0;
