//! A sensor's stability report (`GET /v1/sensors/{sensor_id}/stability`,
//! and its page): its coefficients over its history — spread, drift,
//! control chart and the latest change (definitions in
//! `accelcal_core::history`).

use accelcal_core::TermMap;
use accelcal_core::coverage::Coverage;
use std::collections::BTreeMap;

use accelcal_core::history::{SECONDS_PER_YEAR, TermStability, quantity};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use super::AppState;
use super::lookup::sensor;
use super::problem::Problem;
use crate::domain::review::Basis;
use crate::domain::sensor_types::DEFAULT_COVERAGE_FACTOR;
use crate::domain::timestamp::Timestamp;
use crate::store::{CalibrationSummary, Named, SensorSummary};

/// The query of the stability report.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct StabilityParams {
    /// Only calibrations performed at or after this instant (RFC 3339).
    #[param(value_type = Option<String>, format = DateTime)]
    pub from: Option<String>,
    /// Only calibrations performed at or before this instant (RFC 3339).
    #[param(value_type = Option<String>, format = DateTime)]
    pub to: Option<String>,
}

/// The most calibrations a stability report (and a sensor's page) covers:
/// the latest of the window. Decades of yearly, or years of monthly,
/// calibrations; a longer history is seen a window at a time.
pub const MAX_SERIES: usize = 250;

/// A sensor's stability over a window of its history.
#[derive(Debug, Serialize, ToSchema)]
pub struct Stability {
    /// The sensor.
    pub sensor_id: String,
    /// Calibrations covered: the window's latest, at most 250.
    pub calibrations: usize,
    /// The output unit of every value reported: the latest calibration's.
    pub unit: Option<String>,
    /// Calibrations in the window left out because they are in another
    /// unit (stability never mixes units).
    pub other_units: usize,
    /// Earlier calibrations of the window left out by the cap of 250
    /// (narrow `from`/`to` to cover them).
    pub omitted: usize,
    /// The first one's `performed_at`.
    pub first_performed_at: Option<Timestamp>,
    /// The last one's `performed_at`.
    pub last_performed_at: Option<Timestamp>,
    /// The coverage factor of `latest_change_expanded`: the sensor type's
    /// fixed factor, else the large-sample (normal) factor of its coverage
    /// probability (2 for 0.9545) — the change between two calibrations
    /// carries no degrees of freedom of its own here.
    pub coverage_factor: f64,
    /// Per term present in every calibration of the window (empty for a
    /// triad).
    #[schema(value_type = std::collections::BTreeMap<String, super::openapi::TermStabilitySchema>)]
    pub terms: TermMap<TermStability>,
    /// A triad's: per element of `b`, `S` and `T` (`b_x`, `S_xy`, `T_zz`),
    /// the same figures; a latest change is judged only where both
    /// calibrations give the element a standard error (`S` from known
    /// orientations, `T` from unknown ones).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<std::collections::BTreeMap<String, super::openapi::TermStabilitySchema>>)]
    pub elements: Option<BTreeMap<String, TermStability>>,
    /// Which calibrations the report covers: `not_rejected` (every
    /// calibration not rejected, withdrawn or superseded) or
    /// `approved_only` (`--require-approval`), as the coefficients do.
    pub basis: Basis,
}

/// The stability of every quantity all of `series` (oldest first) have,
/// by name, in the order the first lists them — a single axis's terms and
/// a triad's elements alike (a triad calibrated once with `S2` and once
/// without is reported over `b`, `S` and `T`).
fn by_name(series: &[CalibrationSummary], k: f64) -> Vec<(String, TermStability)> {
    let per: Vec<Vec<Named>> = series.iter().map(CalibrationSummary::quantities).collect();
    let Some(first) = per.first() else {
        return Vec::new();
    };
    let ids: Vec<String> = series.iter().map(|c| c.id.to_string()).collect();
    let ids: Vec<&str> = ids.iter().map(String::as_str).collect();
    let t: Vec<f64> = series.iter().map(|c| years(c.performed_at)).collect();
    first
        .iter()
        .enumerate()
        .filter_map(|(i, q)| {
            // At the same place in every calibration of one model; found by
            // name where the models differ.
            let each: Vec<&Named> = per
                .iter()
                .map(|p| {
                    p.get(i)
                        .filter(|n| n.name == q.name)
                        .or_else(|| p.iter().find(|n| n.name == q.name))
                })
                .collect::<Option<_>>()?;
            let x: Vec<f64> = each.iter().map(|n| n.value).collect();
            let se: Vec<Option<f64>> = each.iter().map(|n| n.std_error).collect();
            Some((q.name.clone(), quantity(&ids, &t, &x, &se, k)))
        })
        .collect()
}

/// A sensor, its calibrations in a window (oldest first) and their stability.
pub struct Report {
    /// The sensor now.
    pub sensor: SensorSummary,
    /// Its calibrations performed within the window, oldest first.
    pub series: Vec<CalibrationSummary>,
    /// Their stability.
    pub stability: Stability,
}

/// The stability of `sensor_id`'s calibrations performed within
/// `from..=to` (404 for an unknown sensor).
/// The coverage factor of a change between two calibrations: a fixed
/// factor as it is, a probability's normal quantile (rounded to 0.01, so
/// that 0.9545 gives 2).
fn large_sample_factor(c: Coverage) -> f64 {
    match c {
        Coverage::Factor(k) => k,
        Coverage::Probability(p) => {
            (accelcal_core::coverage::factor(p, None) * 100.0).round() / 100.0
        }
    }
}

pub async fn report_of(
    state: &AppState,
    sensor_id: &str,
    from: Option<Timestamp>,
    to: Option<Timestamp>,
) -> Result<Report, Problem> {
    let summary = sensor(state, sensor_id).await?;
    let coverage_factor = match &summary.sensor_type {
        Some(t) => state
            .store
            .sensor_type(t.clone())
            .await?
            .map_or(DEFAULT_COVERAGE_FACTOR, |t| {
                large_sample_factor(t.coverage())
            }),
        None => DEFAULT_COVERAGE_FACTOR,
    };
    let found = state
        .store
        .series(sensor_id.to_owned(), from, to, MAX_SERIES, state.web.basis)
        .await?;
    let omitted = found.in_window.saturating_sub(found.items.len());
    // One unit: the latest calibration's.
    let unit = found.items.last().map(|c| c.unit.clone());
    let in_window = found.items.len();
    let series: Vec<CalibrationSummary> = found
        .items
        .into_iter()
        .filter(|c| Some(&c.unit) == unit.as_ref())
        .collect();
    let other_units = in_window - series.len();
    let named = by_name(&series, coverage_factor);
    let triad = !series.is_empty() && series.iter().all(|c| c.triad.is_some());
    let (terms, elements) = if triad {
        (TermMap(Vec::new()), Some(named.into_iter().collect()))
    } else {
        let terms = named
            .into_iter()
            .filter_map(|(name, s)| Some((name.parse().ok()?, s)))
            .collect();
        (TermMap(terms), None)
    };
    let stability = Stability {
        sensor_id: sensor_id.to_owned(),
        calibrations: series.len(),
        unit,
        other_units,
        omitted,
        first_performed_at: series.first().map(|c| c.performed_at),
        last_performed_at: series.last().map(|c| c.performed_at),
        coverage_factor,
        terms,
        elements,
        basis: state.web.basis,
    };
    Ok(Report {
        sensor: summary,
        series,
        stability,
    })
}

/// An instant in years of 365.25 days since the Unix epoch (the abscissa of
/// the drift fit).
pub fn years(t: Timestamp) -> f64 {
    t.unix_micros() as f64 / 1e6 / SECONDS_PER_YEAR
}
