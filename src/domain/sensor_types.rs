//! Sensor types: the limits a sensor's fused coefficients must meet, the
//! decision rule, the coverage of its expanded uncertainties — a coverage
//! probability (the coverage factor then follows from each coefficient's
//! effective degrees of freedom, [`accelcal_core::coverage`]) or a fixed
//! coverage factor (the probability then follows) — and its calibration
//! interval.

pub use super::limits::{
    MAX_COVERAGE_FACTOR, MAX_COVERAGE_PROBABILITY, MAX_INTERVAL_DAYS, MIN_COVERAGE_FACTOR,
    MIN_COVERAGE_PROBABILITY,
};
use accelcal_core::TermMap;
use accelcal_core::coverage::{Coverage, DEFAULT_PROBABILITY};
use accelcal_core::decision::{Limit, Rule};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::field::{Errors, Invalid, Loc};
use super::limits::{MAX_LABEL_CHARS, MAX_UNIT_CHARS};
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// The large-sample coverage factor of [`DEFAULT_PROBABILITY`] (a
/// normal distribution), for comparisons that carry no degrees of freedom
/// (a stability report's latest change).
pub const DEFAULT_COVERAGE_FACTOR: f64 = 2.0;
/// Calibration interval when a type gives none, in days.
pub const DEFAULT_INTERVAL_DAYS: u32 = 365;

/// The body of `PUT /v1/sensor-types/{type_id}`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SensorTypeBody {
    /// A label (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub label: Option<String>,
    /// The output unit the limits are in (as a submission's `unit`, at most
    /// 32 characters): a calibration in another unit is refused.
    #[schema(schema_with = crate::domain::schema::unit)]
    pub unit: String,
    /// Limits per term on the fused coefficients, in `unit`:
    /// `{"k0": {"min": -0.001, "max": 0.001}}`.
    #[schema(schema_with = crate::domain::schema::limits)]
    pub limits: TermMap<Limit>,
    /// `simple` (the value against the limits) or `guarded` (ILAC-G8,
    /// with the expanded uncertainty as guard band).
    #[schema(value_type = crate::domain::schema::RuleSchema)]
    pub decision_rule: Rule,
    /// The coverage probability of the expanded uncertainties (default
    /// 0.9545): each coefficient's coverage factor is Student's t for it at
    /// the coefficient's effective degrees of freedom. Not with
    /// `coverage_factor`.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::coverage_probability)]
    pub coverage_probability: Option<f64>,
    /// A fixed coverage factor instead (each coefficient then states the
    /// probability it achieves at its effective degrees of freedom). Not
    /// with `coverage_probability`.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::coverage_factor)]
    pub coverage_factor: Option<f64>,
    /// Calibration interval in days (default 365): `due_at` is the
    /// calibration's `performed_at` plus this.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::interval_days)]
    pub interval_days: Option<i64>,
}

/// A sensor type as stored and served.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SensorType {
    /// Its id.
    pub type_id: String,
    /// Its label.
    pub label: Option<String>,
    /// The output unit its limits are in (null for types written before
    /// types declared one: their calibrations' units are not compared).
    #[serde(default)]
    pub unit: Option<String>,
    /// Limits per term.
    #[schema(schema_with = crate::domain::schema::limits)]
    pub limits: TermMap<Limit>,
    /// The decision rule.
    #[schema(value_type = crate::domain::schema::RuleSchema)]
    pub decision_rule: Rule,
    /// The coverage probability of the expanded uncertainties (null when
    /// the type fixes the coverage factor).
    #[serde(default)]
    pub coverage_probability: Option<f64>,
    /// The fixed coverage factor (null when the type states a probability).
    /// A type written before coverage probabilities keeps the factor it was
    /// written with (2 when it gave none).
    pub coverage_factor: Option<f64>,
    /// Calibration interval in days.
    pub interval_days: u32,
    /// When it was last written.
    pub updated_at: Timestamp,
}

impl SensorType {
    /// What its expanded uncertainties hold fixed.
    pub fn coverage(&self) -> Coverage {
        match (self.coverage_probability, self.coverage_factor) {
            (Some(p), _) => Coverage::Probability(p),
            (None, Some(k)) => Coverage::Factor(k),
            (None, None) => Coverage::default(),
        }
    }
}

impl SensorType {
    /// Why outputs in `unit` cannot be judged by this type, whose limits are
    /// in another unit (at `/unit`).
    pub fn unit_refusal(&self, unit: &str) -> Option<Invalid> {
        let limits_unit = self.unit.as_ref().filter(|u| **u != unit)?;
        let unit = super::text::echo(unit);
        Some(Invalid::one(
            Loc::Root.key("unit"),
            format!(
                "is `{unit}`, but sensor type `{}` sets its limits in `{limits_unit}`: send the \
                 outputs in `{limits_unit}`, or give the sensor a type in `{unit}`",
                self.type_id
            ),
        ))
    }

    /// The refusal of a model that lacks `term`, on which this type sets
    /// limits (at `/model`).
    pub fn missing_term(&self, term: accelcal_core::Term) -> Invalid {
        Invalid::one(
            Loc::Root.key("model"),
            format!(
                "sensor type `{}` sets limits on `{term}`, which this model does not identify; \
                 add `{term}` to the model",
                self.type_id
            ),
        )
    }
}

/// The coverage of a sensor's expanded uncertainties: its type's, else the
/// default probability.
pub fn coverage(t: Option<&SensorType>) -> Coverage {
    t.map_or(Coverage::default(), SensorType::coverage)
}

impl SensorTypeBody {
    /// Checks the body and makes the type `type_id` of it; every problem is
    /// reported.
    pub fn check(self, type_id: String, now: Timestamp) -> Result<SensorType, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        if let Some(l) = &self.label
            && let Err(why) = check_str(l, MAX_LABEL_CHARS, Chars::Line)
        {
            errors.add(root.key("label"), why);
        }
        if let Err(why) = check_str(&self.unit, MAX_UNIT_CHARS, Chars::Line) {
            errors.add(root.key("unit"), why);
        }
        let limits_at = root.key("limits");
        if self.limits.is_empty() {
            errors.add(
                limits_at,
                "needs at least one limit: a type that limits nothing would pass every \
                 calibration having checked nothing",
            );
        }
        for (term, limit) in self.limits.iter() {
            let at = limits_at.key(term.name());
            for (name, v) in [("min", limit.min), ("max", limit.max)] {
                if v.is_some_and(|x| !x.is_finite()) {
                    errors.add(at.key(name), "must be a finite number");
                }
            }
            match (limit.min, limit.max) {
                (None, None) => errors.add(at, "needs `min`, `max` or both"),
                (Some(lo), Some(hi)) if lo > hi => {
                    errors.add(at, format!("`min` ({lo}) is above `max` ({hi})"))
                }
                _ => {}
            }
        }
        let coverage_probability = match (self.coverage_probability, self.coverage_factor) {
            (None, None) => Some(DEFAULT_PROBABILITY),
            (p, _) => p,
        };
        if let Some(p) = self.coverage_probability
            && !(MIN_COVERAGE_PROBABILITY..=MAX_COVERAGE_PROBABILITY).contains(&p)
        {
            errors.add(
                root.key("coverage_probability"),
                format!(
                    "must be from {MIN_COVERAGE_PROBABILITY} to {MAX_COVERAGE_PROBABILITY} \
                     (0.9545: about two standard deviations)"
                ),
            );
        }
        if let Some(k) = self.coverage_factor {
            if self.coverage_probability.is_some() {
                errors.add(
                    root.key("coverage_factor"),
                    "is given with `coverage_probability`: a type fixes one of them, and the \
                     other follows from each coefficient's effective degrees of freedom",
                );
            } else if !(MIN_COVERAGE_FACTOR..=MAX_COVERAGE_FACTOR).contains(&k) {
                errors.add(
                    root.key("coverage_factor"),
                    format!(
                        "must be from {MIN_COVERAGE_FACTOR} to {MAX_COVERAGE_FACTOR} (or give \
                         `coverage_probability` instead, and k follows from the degrees of \
                         freedom)"
                    ),
                );
            }
        }
        let interval = self
            .interval_days
            .unwrap_or(i64::from(DEFAULT_INTERVAL_DAYS));
        if !(1..=i64::from(MAX_INTERVAL_DAYS)).contains(&interval) {
            errors.add(
                root.key("interval_days"),
                format!("must be a whole number of days from 1 to {MAX_INTERVAL_DAYS}"),
            );
        }
        let mut limits = self.limits.0;
        limits.sort_by_key(|(t, _)| *t);
        errors.finish(|| SensorType {
            type_id,
            label: self.label,
            unit: Some(self.unit),
            limits: TermMap(limits),
            decision_rule: self.decision_rule,
            coverage_probability,
            coverage_factor: self
                .coverage_factor
                .filter(|_| coverage_probability.is_none()),
            interval_days: interval as u32,
            updated_at: now,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::typed::{BodyError, from_json};

    fn check(body: &str) -> Result<SensorType, Vec<String>> {
        let now = Timestamp::parse("2026-11-22T00:00:00Z").unwrap();
        from_json::<SensorTypeBody>(body.as_bytes())
            .map_err(|e| match e {
                BodyError::Invalid(i) => i,
                BodyError::Syntax(s) => panic!("{s}"),
            })
            .and_then(|b| b.check("T-1".into(), now))
            .map_err(|i| i.errors.into_iter().map(|e| e.pointer).collect())
    }

    /// A limit may pin a coefficient to one value (`min` = `max`); `min`
    /// above `max` is named.
    #[test]
    fn a_limit_may_be_a_single_value_but_not_inverted() {
        let t =
            check(r#"{"unit": "mA", "limits": {"k0": {"min": 1e-3, "max": 1e-3}}, "decision_rule": "simple"}"#)
                .unwrap();
        assert_eq!(t.limits.len(), 1);
        assert_eq!(
            check(r#"{"unit": "mA", "limits": {"k0": {"min": 1.0000001e-3, "max": 1e-3}}, "decision_rule": "simple"}"#)
                .unwrap_err(),
            ["/limits/k0"]
        );
    }

    /// A type judges something: at least one limit, and a coverage factor
    /// from 1 to 10 (the issue's 1e-300 is refused; both ends are accepted)
    /// or a coverage probability from 0.5 to 0.9999, never both.
    #[test]
    fn a_type_must_limit_something_with_a_meaningful_coverage_factor() {
        assert_eq!(
            check(r#"{"unit": "mA", "limits": {}, "decision_rule": "simple"}"#).unwrap_err(),
            ["/limits"]
        );
        let with = |k: &str| {
            check(&format!(
                r#"{{"unit": "mA", "limits": {{"k0": {{"max": 1}}}}, "decision_rule": "guarded", "coverage_factor": {k}}}"#
            ))
        };
        for bad in ["1e-300", "0.999", "10.001"] {
            assert_eq!(with(bad).unwrap_err(), ["/coverage_factor"], "{bad}");
        }
        assert_eq!(with("1").unwrap().coverage(), Coverage::Factor(1.0));
        assert_eq!(with("10").unwrap().coverage(), Coverage::Factor(10.0));
        assert_eq!(with("10").unwrap().coverage_probability, None);
        let with_p = |p: &str| {
            check(&format!(
                r#"{{"unit": "mA", "limits": {{"k0": {{"max": 1}}}}, "decision_rule": "guarded", "coverage_probability": {p}}}"#
            ))
        };
        for bad in ["0", "0.49", "1", "0.99991"] {
            assert_eq!(with_p(bad).unwrap_err(), ["/coverage_probability"], "{bad}");
        }
        assert_eq!(
            with_p("0.99").unwrap().coverage(),
            Coverage::Probability(0.99)
        );
        assert_eq!(
            check(r#"{"unit": "mA", "limits": {"k0": {"max": 1}}, "decision_rule": "simple", "coverage_probability": 0.95, "coverage_factor": 2}"#)
                .unwrap_err(),
            ["/coverage_factor"]
        );
    }

    #[test]
    fn a_type_is_checked_field_by_field() {
        let t = check(r#"{"unit": "mA", "limits": {"kp": {"max": 0.01}, "k0": {"min": -1e-3, "max": 1e-3}}, "decision_rule": "guarded"}"#).unwrap();
        assert_eq!(
            (t.coverage(), t.interval_days),
            (Coverage::Probability(DEFAULT_PROBABILITY), 365)
        );
        let names: Vec<&str> = t.limits.iter().map(|(t, _)| t.name()).collect();
        assert_eq!(names, ["k0", "kp"], "limits in model order");
        assert_eq!(
            check(r#"{"unit": "mA", "limits": {"k0": {"min": 1, "max": -1}, "ki": {}}, "decision_rule": "simple", "coverage_factor": 0, "interval_days": -5}"#).unwrap_err(),
            ["/limits/k0", "/limits/ki", "/coverage_factor", "/interval_days"]
        );
        assert_eq!(
            check(r#"{"unit": "mA", "limits": {"k9": {"min": 1}}, "decision_rule": "simple"}"#)
                .unwrap_err(),
            ["/limits/k9"]
        );
        assert_eq!(
            check(r#"{"unit": "mA", "limits": {"k0": {"max": 1}}, "decision_rule": "lenient"}"#)
                .unwrap_err(),
            ["/decision_rule"]
        );
        assert_eq!(
            check(r#"{"unit": "mA", "limits": {"k0": {"mn": 1}}, "decision_rule": "simple"}"#)
                .unwrap_err(),
            ["/limits/k0/mn"]
        );
    }
}

#[cfg(test)]
mod units {
    use super::*;
    use crate::domain::typed::{BodyError, from_json};

    /// A type declares the unit its limits are in; it is stored with it.
    #[test]
    fn a_type_declares_its_unit() {
        let now = Timestamp::parse("2026-11-22T00:00:00Z").unwrap();
        let body = |b: &str| from_json::<SensorTypeBody>(b.as_bytes());
        match body(r#"{"limits": {"k0": {"max": 1}}, "decision_rule": "simple"}"#) {
            Err(BodyError::Invalid(i)) => assert_eq!(i.errors[0].pointer, "/unit"),
            other => panic!("{other:?}"),
        }
        let t = body(r#"{"unit": "mA", "limits": {"k0": {"max": 1}}, "decision_rule": "simple"}"#)
            .unwrap()
            .check("T".into(), now)
            .unwrap();
        assert_eq!(t.unit.as_deref(), Some("mA"));
        let bad =
            body(r#"{"unit": "m\nA", "limits": {"k0": {"max": 1}}, "decision_rule": "simple"}"#)
                .unwrap()
                .check("T".into(), now)
                .unwrap_err();
        assert_eq!(bad.errors[0].pointer, "/unit");
        // A type stored before types declared a unit reads back without one.
        let old: SensorType = serde_json::from_str(
            r#"{"type_id": "OLD", "label": null, "limits": {"k0": {"max": 1}}, "decision_rule": "simple", "coverage_factor": 2, "interval_days": 365, "updated_at": "2026-01-01T00:00:00Z"}"#,
        )
        .unwrap();
        assert_eq!(old.unit, None);
        // And keeps the coverage factor it was written with.
        assert_eq!(old.coverage(), Coverage::Factor(2.0));
    }
}
