//! `POST /v1/sensors/{sensor_id}/compensate`: input accelerations from raw
//! outputs, inverting a stored calibration's model — a single-axis model
//! output by output, or a triad's `g = S⁻¹ (u − b)` triple by triple.

use std::fmt;

use accelcal_core::decision::Verdict;
use accelcal_core::triad::{Triad, TriadError};
use accelcal_core::{Compensator, Gravity, Model, TermMap};
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};
use uuid::Uuid;

use super::field::{Errors, Invalid, Loc};
use super::limits::{MAX_CROSS_G, MAX_OUTPUTS, MAX_READING};
use super::review::{Basis, State};
use super::timestamp::Timestamp;
use super::usability::Usability;

mod thermal;

pub use thermal::{TemperatureUsed, Temperatures, no_model, outside_range};

/// The body of a compensation request.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CompensateRequest {
    /// Raw outputs, in the calibration's unit (1 to 10 000, each of
    /// magnitude at most 1e9): numbers for a single-axis sensor, triples
    /// `[u_x, u_y, u_z]` for a triad.
    #[schema(schema_with = crate::domain::schema::outputs)]
    pub outputs: Outputs,
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
    /// The sensor's temperature, °C, for a calibration that is a
    /// temperature model (required then, refused otherwise): one number
    /// for every output, or one per output.
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub temperature_c: Option<Temperatures>,
    /// Use a temperature model outside its valid range (the answer then
    /// says `extrapolated` and by how many kelvin); default false.
    #[serde(default)]
    pub allow_extrapolation: bool,
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
    /// A single-axis sensor's: one input acceleration (g) per output.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub a_i: Option<Vec<f64>>,
    /// A triad's: the specific force `[g_x, g_y, g_z]` (g) per triple of
    /// outputs, `g = S⁻¹ (u − b)`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub g: Option<Vec<[f64; 3]>>,
    /// For a temperature model: the temperature its coefficients were
    /// evaluated at, its range and whether it was extrapolated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature: Option<TemperatureUsed>,
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

/// Raw outputs: numbers (a single-axis sensor) or triples (a triad).
#[derive(Debug, Clone, PartialEq)]
pub enum Outputs {
    /// One output each.
    Axis(Vec<f64>),
    /// `[u_x, u_y, u_z]` each.
    Triad(Vec<[f64; 3]>),
}

impl Outputs {
    /// How many outputs (or triples).
    pub fn len(&self) -> usize {
        match self {
            Outputs::Axis(v) => v.len(),
            Outputs::Triad(v) => v.len(),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One element of `outputs`: a number or a triple.
enum Element {
    Number(f64),
    Triple([f64; 3]),
}

impl<'de> Deserialize<'de> for Element {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Element;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number, or a triple of numbers [u_x, u_y, u_z]")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Element, E> {
                Ok(Element::Number(x))
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Element, E> {
                Ok(Element::Number(x as f64))
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Element, E> {
                Ok(Element::Number(x as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Element, A::Error> {
                let mut t = [0.0; 3];
                for (k, x) in t.iter_mut().enumerate() {
                    *x = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(k, &self))?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(Element::Triple(t))
            }
        }
        d.deserialize_any(V)
    }
}

impl<'de> Deserialize<'de> for Outputs {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Outputs;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("an array of numbers, or of triples [u_x, u_y, u_z]")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Outputs, A::Error> {
                let (mut axis, mut triad) = (Vec::new(), Vec::new());
                while let Some(e) = seq.next_element::<Element>()? {
                    match e {
                        Element::Number(x) => axis.push(x),
                        Element::Triple(t) => triad.push(t),
                    }
                    if !axis.is_empty() && !triad.is_empty() {
                        return Err(de::Error::custom(
                            "mixes numbers and triples: numbers for a single-axis sensor, \
                             triples [u_x, u_y, u_z] for a triad",
                        ));
                    }
                }
                Ok(if triad.is_empty() {
                    Outputs::Axis(axis)
                } else {
                    Outputs::Triad(triad)
                })
            }
        }
        d.deserialize_seq(V)
    }
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
        if matches!(self.outputs, Outputs::Triad(_)) {
            return out;
        }
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
        match &self.outputs {
            Outputs::Axis(v) => numbers("outputs", v, MAX_READING, None),
            Outputs::Triad(v) => {
                let at = root.key("outputs");
                if !(1..=MAX_OUTPUTS).contains(&n) {
                    errors.add(at, format!("must hold 1 to {MAX_OUTPUTS} triples, not {n}"));
                }
                for (k, t) in v.iter().enumerate().take(MAX_OUTPUTS) {
                    if t.iter().any(|x| x.abs() > MAX_READING) {
                        errors.add(
                            at.index(k),
                            format!("each output must be of magnitude at most {MAX_READING:e}"),
                        );
                    }
                }
                for key in ["a_p", "a_o"] {
                    let given = if key == "a_p" { &self.a_p } else { &self.a_o };
                    if given.is_some() {
                        errors.add(
                            root.key(key),
                            "is for single-axis outputs: a triad's triples give every axis",
                        );
                    }
                }
                return errors.finish(|| self);
            }
        }
        if let Some(v) = &self.a_p {
            numbers("a_p", v, MAX_CROSS_G, Some(n));
        }
        if let Some(v) = &self.a_o {
            numbers("a_o", v, MAX_CROSS_G, Some(n));
        }
        if let Some(t) = &self.temperature_c {
            t.check(n, &mut errors);
        }
        errors.finish(|| self)
    }

    /// The input acceleration for every output, with `coefficients` (a
    /// stored calibration's fused values, `id` naming it in messages).
    pub fn compensate(&self, coefficients: &TermMap<f64>, id: Uuid) -> Result<Vec<f64>, Invalid> {
        let root = Loc::Root;
        let Outputs::Axis(outputs) = &self.outputs else {
            return Err(Invalid::one(
                root.key("outputs"),
                format!(
                    "calibration {id} is of a single-axis sensor: give one number per output, \
                     not triples"
                ),
            ));
        };
        let comp = Compensator::new(coefficients).map_err(|e| {
            Invalid::one(
                root.key("calibration_id"),
                format!("calibration {id} cannot be used: {e}"),
            )
        })?;
        let mut errors = Errors::default();
        let outputs_at = root.key("outputs");
        let a_i = outputs
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

    /// The specific force for every triple of outputs with a triad's model
    /// `triad`: `g = S⁻¹ (u − b)`, or with second-order terms Newton's
    /// solution ([`Triad::compensate`], which refuses an `S` singular to
    /// working precision, and outputs the second-order model cannot give).
    pub fn compensate_triad(&self, triad: &Triad, id: Uuid) -> Result<Vec<[f64; 3]>, Invalid> {
        let root = Loc::Root;
        let Outputs::Triad(outputs) = &self.outputs else {
            return Err(Invalid::one(
                root.key("outputs"),
                format!(
                    "calibration {id} is a triad's: give each output as a triple [u_x, u_y, u_z]"
                ),
            ));
        };
        let mut errors = Errors::default();
        let outputs_at = root.key("outputs");
        let mut unusable = false;
        let g = outputs
            .iter()
            .enumerate()
            .map(|(k, u)| {
                triad.compensate(*u).unwrap_or_else(|e| {
                    let why = format!("calibration {id} cannot compensate these: {e}");
                    match e {
                        TriadError::NoSolution => errors.add(outputs_at.index(k), why),
                        // The calibration's own fault: said once.
                        _ if std::mem::replace(&mut unusable, true) => {}
                        _ => errors.add(root.key("calibration_id"), why),
                    }
                    [0.0; 3]
                })
            })
            .collect();
        errors.finish(|| g)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(outputs: Vec<f64>, a_p: Option<Vec<f64>>) -> CompensateRequest {
        CompensateRequest {
            outputs: Outputs::Axis(outputs),
            a_p,
            a_o: None,
            calibration_id: None,
            temperature_c: None,
            allow_extrapolation: false,
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
            outputs: Outputs::Axis(vec![1.0]),
            a_p: None,
            a_o: None,
            calibration_id: None,
            temperature_c: None,
            allow_extrapolation: false,
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
