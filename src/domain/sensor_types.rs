//! Sensor types: the limits a sensor's fused coefficients must meet, the
//! decision rule, the coverage factor of its expanded uncertainties and its
//! calibration interval.

use accelcal_core::TermMap;
use accelcal_core::decision::{Limit, Rule};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::field::{Errors, Invalid, Loc};
use super::limits::MAX_LABEL_CHARS;
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// Coverage factor when a type gives none (about 95 % for a normal distribution).
pub const DEFAULT_COVERAGE_FACTOR: f64 = 2.0;
/// Calibration interval when a type gives none, in days.
pub const DEFAULT_INTERVAL_DAYS: u32 = 365;
/// Largest coverage factor accepted.
pub const MAX_COVERAGE_FACTOR: f64 = 10.0;
/// Longest calibration interval accepted, in days (ten years).
pub const MAX_INTERVAL_DAYS: u32 = 3650;

/// The body of `PUT /v1/sensor-types/{type_id}`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SensorTypeBody {
    /// A label (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub label: Option<String>,
    /// Limits per term on the fused coefficients, in the calibrations'
    /// output unit: `{"k0": {"min": -0.001, "max": 0.001}}`.
    #[schema(schema_with = crate::domain::schema::limits)]
    pub limits: TermMap<Limit>,
    /// `simple` (the value against the limits) or `guarded` (ILAC-G8,
    /// with the expanded uncertainty as guard band).
    #[schema(value_type = crate::domain::schema::RuleSchema)]
    pub decision_rule: Rule,
    /// Coverage factor of the expanded uncertainties (default 2).
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
    /// Limits per term.
    #[schema(schema_with = crate::domain::schema::limits)]
    pub limits: TermMap<Limit>,
    /// The decision rule.
    #[schema(value_type = crate::domain::schema::RuleSchema)]
    pub decision_rule: Rule,
    /// Coverage factor of the expanded uncertainties.
    pub coverage_factor: f64,
    /// Calibration interval in days.
    pub interval_days: u32,
    /// When it was last written.
    pub updated_at: Timestamp,
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
        let limits_at = root.key("limits");
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
        let coverage_factor = self.coverage_factor.unwrap_or(DEFAULT_COVERAGE_FACTOR);
        if !(coverage_factor > 0.0 && coverage_factor <= MAX_COVERAGE_FACTOR) {
            errors.add(
                root.key("coverage_factor"),
                format!("must be above 0 and at most {MAX_COVERAGE_FACTOR}"),
            );
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
            limits: TermMap(limits),
            decision_rule: self.decision_rule,
            coverage_factor,
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
            check(r#"{"limits": {"k0": {"min": 1e-3, "max": 1e-3}}, "decision_rule": "simple"}"#)
                .unwrap();
        assert_eq!(t.limits.len(), 1);
        assert_eq!(
            check(r#"{"limits": {"k0": {"min": 1.0000001e-3, "max": 1e-3}}, "decision_rule": "simple"}"#)
                .unwrap_err(),
            ["/limits/k0"]
        );
    }

    #[test]
    fn a_type_is_checked_field_by_field() {
        let t = check(r#"{"limits": {"kp": {"max": 0.01}, "k0": {"min": -1e-3, "max": 1e-3}}, "decision_rule": "guarded"}"#).unwrap();
        assert_eq!((t.coverage_factor, t.interval_days), (2.0, 365));
        let names: Vec<&str> = t.limits.iter().map(|(t, _)| t.name()).collect();
        assert_eq!(names, ["k0", "kp"], "limits in model order");
        assert_eq!(
            check(r#"{"limits": {"k0": {"min": 1, "max": -1}, "ki": {}}, "decision_rule": "simple", "coverage_factor": 0, "interval_days": -5}"#).unwrap_err(),
            ["/limits/k0", "/limits/ki", "/coverage_factor", "/interval_days"]
        );
        assert_eq!(
            check(r#"{"limits": {"k9": {"min": 1}}, "decision_rule": "simple"}"#).unwrap_err(),
            ["/limits/k9"]
        );
        assert_eq!(
            check(r#"{"limits": {}, "decision_rule": "lenient"}"#).unwrap_err(),
            ["/decision_rule"]
        );
        assert_eq!(
            check(r#"{"limits": {"k0": {"mn": 1}}, "decision_rule": "simple"}"#).unwrap_err(),
            ["/limits/k0/mn"]
        );
    }
}
