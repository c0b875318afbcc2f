//! `POST /v1/sensors/{sensor_id}/compensate`: input accelerations from raw
//! outputs, inverting a stored calibration's model.

use accelcal_core::decision::Verdict;
use accelcal_core::{Compensator, Gravity, Model, TermMap};
use serde::{Deserialize, Serialize};
use uuid::Uuid;

use super::field::{Errors, Invalid, Loc};
use super::limits::{MAX_CROSS_G, MAX_OUTPUTS, MAX_READING};
use super::review::{Basis, State};
use super::timestamp::Timestamp;
use super::usability::Usability;

/// The body of a compensation request.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CompensateRequest {
    /// Raw outputs, in the calibration's unit (1 to 10 000, each of
    /// magnitude at most 1e9).
    #[schema(schema_with = crate::domain::schema::outputs)]
    pub outputs: Vec<f64>,
    /// Known `a_p` (g), one per output; default 0.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::cross_axis)]
    pub a_p: Option<Vec<f64>>,
    /// Known `a_o` (g), one per output; default 0.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::cross_axis)]
    pub a_o: Option<Vec<f64>>,
    /// Use this calibration of the sensor instead of the latest.
    #[serde(default)]
    pub calibration_id: Option<Uuid>,
}

/// The answer of a compensation.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
#[schema(as = CompensateResult)]
pub struct Compensated {
    /// The sensor.
    pub sensor_id: String,
    /// The calibration whose model was inverted.
    pub calibration_id: Uuid,
    /// When it was performed.
    pub performed_at: Timestamp,
    /// Its verdict against the sensor type's limits (null when untyped).
    #[schema(value_type = Option<crate::domain::schema::VerdictSchema>)]
    pub verdict: Option<Verdict>,
    /// When the sensor is due again (null when untyped).
    pub due_at: Option<Timestamp>,
    /// The sensor's status by it, whether its coefficients are usable, and
    /// why not.
    #[serde(flatten)]
    pub usability: Usability,
    /// The cross-axis inputs (`a_p`, `a_o`) that were not given and were
    /// taken as 0 although the model has terms in them.
    pub assumed_zero: Vec<CrossAxis>,
    /// The outputs' unit.
    pub unit: String,
    /// One input acceleration (g) per output.
    pub a_i: Vec<f64>,
    /// The calibration's state (one that does not count on `basis` is not
    /// usable).
    pub state: State,
    /// Which calibrations are served: `not_rejected` or `approved_only`.
    pub basis: Basis,
}

/// A cross-axis input of compensation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
pub enum CrossAxis {
    /// The pendulous axis.
    #[serde(rename = "a_p")]
    AP,
    /// The output axis.
    #[serde(rename = "a_o")]
    AO,
}

impl CompensateRequest {
    /// The cross-axis inputs this request leaves out although `model` has
    /// terms in them: compensation takes them as 0.
    pub fn assumed_zero(&self, model: &Model) -> Vec<CrossAxis> {
        // A term has an axis in it when its gradient there is not zero at a
        // point off every axis.
        let generic = Gravity::from([0.3, 0.4, 0.5]);
        let uses = |axis: usize| {
            model
                .terms()
                .iter()
                .any(|t| t.gradient(&generic)[axis] != 0.0)
        };
        let mut out = Vec::new();
        if self.a_p.is_none() && uses(1) {
            out.push(CrossAxis::AP);
        }
        if self.a_o.is_none() && uses(2) {
            out.push(CrossAxis::AO);
        }
        out
    }

    /// Checks sizes and ranges; every problem is reported.
    pub fn check(self) -> Result<CompensateRequest, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        let n = self.outputs.len();
        let mut numbers = |key: &'static str, xs: &[f64], bound: f64, len: Option<usize>| {
            let at = root.key(key);
            if !(1..=MAX_OUTPUTS).contains(&xs.len()) {
                errors.add(
                    at,
                    format!("must hold 1 to {MAX_OUTPUTS} values, not {}", xs.len()),
                );
                return;
            }
            if let Some(n) = len.filter(|n| *n != xs.len()) {
                errors.add(
                    at,
                    format!("must hold one value per output ({n}), not {}", xs.len()),
                );
                return;
            }
            for (k, x) in xs.iter().enumerate() {
                if x.abs() > bound {
                    errors.add(
                        at.index(k),
                        format!("must be of magnitude at most {bound:e}"),
                    );
                }
            }
        };
        numbers("outputs", &self.outputs, MAX_READING, None);
        if let Some(v) = &self.a_p {
            numbers("a_p", v, MAX_CROSS_G, Some(n));
        }
        if let Some(v) = &self.a_o {
            numbers("a_o", v, MAX_CROSS_G, Some(n));
        }
        errors.finish(|| self)
    }

    /// The input acceleration for every output, with `coefficients` (a
    /// stored calibration's fused values, `id` naming it in messages).
    pub fn compensate(&self, coefficients: &TermMap<f64>, id: Uuid) -> Result<Vec<f64>, Invalid> {
        let root = Loc::Root;
        let comp = Compensator::new(coefficients).map_err(|e| {
            Invalid::one(
                root.key("calibration_id"),
                format!("calibration {id} cannot be used: {e}"),
            )
        })?;
        let mut errors = Errors::default();
        let outputs_at = root.key("outputs");
        let a_i = self
            .outputs
            .iter()
            .enumerate()
            .map(|(k, u)| {
                let ap = self.a_p.as_ref().map_or(0.0, |v| v[k]);
                let ao = self.a_o.as_ref().map_or(0.0, |v| v[k]);
                comp.input(*u, ap, ao).unwrap_or_else(|e| {
                    errors.add(outputs_at.index(k), e.to_string());
                    0.0
                })
            })
            .collect();
        errors.finish(|| a_i)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(outputs: Vec<f64>, a_p: Option<Vec<f64>>) -> CompensateRequest {
        CompensateRequest {
            outputs,
            a_p,
            a_o: None,
            calibration_id: None,
        }
    }

    fn pointers(e: Invalid) -> Vec<String> {
        e.errors.iter().map(|f| f.pointer.clone()).collect()
    }

    /// Each bound is inclusive: a value of exactly the largest magnitude
    /// allowed passes, the next one up is named.
    #[test]
    fn magnitudes_may_reach_their_bound_but_not_pass_it() {
        let at = request(
            vec![MAX_READING, -MAX_READING],
            Some(vec![MAX_CROSS_G, -MAX_CROSS_G]),
        );
        assert!(at.check().is_ok());
        let over = request(
            vec![MAX_READING, f64::next_up(MAX_READING)],
            Some(vec![f64::next_down(-MAX_CROSS_G), 0.0]),
        );
        assert_eq!(
            pointers(over.check().unwrap_err()),
            ["/outputs/1", "/a_p/0"]
        );
    }
}

#[cfg(test)]
mod assumed {
    use accelcal_core::Term::*;

    use super::*;

    fn model(terms: &[accelcal_core::Term]) -> Model {
        Model::new(terms.to_vec()).unwrap()
    }

    /// The inputs left out that the model has terms in, and only those.
    #[test]
    fn the_answer_names_the_cross_axis_inputs_taken_as_zero() {
        let none = CompensateRequest {
            outputs: vec![1.0],
            a_p: None,
            a_o: None,
            calibration_id: None,
        };
        assert_eq!(none.assumed_zero(&model(&[K0, Ki])), []);
        assert_eq!(none.assumed_zero(&model(&[K0, Ki, Kp])), [CrossAxis::AP]);
        assert_eq!(none.assumed_zero(&model(&[K0, Ki, Koo])), [CrossAxis::AO]);
        assert_eq!(
            none.assumed_zero(&model(&[K0, Ki, Kop])),
            [CrossAxis::AP, CrossAxis::AO]
        );
        assert_eq!(none.assumed_zero(&model(&[K0, Ki, Kii, Kiii])), []);
        let given = CompensateRequest {
            a_p: Some(vec![0.1]),
            ..none.clone()
        };
        assert_eq!(
            given.assumed_zero(&model(&[K0, Ki, Kpi, Kio])),
            [CrossAxis::AO]
        );
        let json = serde_json::to_string(&[CrossAxis::AP, CrossAxis::AO]).unwrap();
        assert_eq!(json, r#"["a_p","a_o"]"#);
    }
}
