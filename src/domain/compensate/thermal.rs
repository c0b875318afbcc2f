//! Compensation and coefficients at a temperature (issue 45 item 3): a
//! temperature model's coefficients evaluated at the sensor's temperature
//! — one for every output, or one per output — and each output inverted
//! with them. A temperature outside the model's valid range is refused
//! unless the caller allows extrapolation; the answer then says by how
//! many kelvin.

use std::collections::HashMap;
use std::fmt;

use accelcal_core::Compensator;
use accelcal_core::triad::Triad;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};
use uuid::Uuid;

use super::super::field::{Errors, Invalid, Loc};
use super::super::limits::TEMPERATURE_C;
use super::super::thermal::{ThermalModel, TriadThermalModel};
use super::{CompensateRequest, Outputs};

/// The sensor's temperature, °C: one for every output, or one each.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Temperatures {
    /// One for all.
    One(f64),
    /// One per output.
    Each(Vec<f64>),
}

impl Temperatures {
    /// Output `k`'s.
    pub fn of(&self, k: usize) -> f64 {
        match self {
            Temperatures::One(t) => *t,
            Temperatures::Each(v) => v.get(k).copied().unwrap_or(f64::NAN),
        }
    }

    /// Where output `k`'s is in a request: its JSON pointer.
    fn at(&self, k: usize) -> String {
        let key = Loc::Root;
        let key = key.key("temperature_c");
        match self {
            Temperatures::One(_) => key.to_string(),
            Temperatures::Each(_) => key.index(k).to_string(),
        }
    }

    /// Its values, each with its place.
    fn values(&self) -> Vec<(String, f64)> {
        match self {
            Temperatures::One(t) => vec![(self.at(0), *t)],
            Temperatures::Each(v) => v
                .iter()
                .enumerate()
                .map(|(k, t)| (self.at(k), *t))
                .collect(),
        }
    }

    /// Checks each is a plausible temperature and, one each, that there is
    /// one per output (`n`).
    pub fn check(&self, n: usize, errors: &mut Errors) {
        if let Temperatures::Each(v) = self
            && v.len() != n
        {
            errors.add(
                Loc::Root.key("temperature_c"),
                format!(
                    "must be one temperature for every output, or one per output ({n}), not {}",
                    v.len()
                ),
            );
            return;
        }
        for (at, t) in self.values() {
            if !TEMPERATURE_C.contains(&t) {
                errors.add(
                    at,
                    format!(
                        "must be a temperature from {} to {} °C",
                        TEMPERATURE_C.start(),
                        TEMPERATURE_C.end()
                    ),
                );
            }
        }
    }
}

impl<'de> Deserialize<'de> for Temperatures {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Temperatures;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a temperature in °C, or an array of one per output")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Temperatures, E> {
                Ok(Temperatures::One(x))
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Temperatures, E> {
                Ok(Temperatures::One(x as f64))
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Temperatures, E> {
                Ok(Temperatures::One(x as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Temperatures, A::Error> {
                let mut v = Vec::new();
                while let Some(t) = seq.next_element::<f64>()? {
                    v.push(t);
                }
                Ok(Temperatures::Each(v))
            }
        }
        d.deserialize_any(V)
    }
}

/// The temperature a temperature model was read at, in an answer.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct TemperatureUsed {
    /// The temperature used, °C (one per output, when given so).
    #[schema(value_type = Object)]
    pub temperature_c: Temperatures,
    /// The model's `T_ref`, °C.
    pub reference_c: f64,
    /// Its valid range `[T_min, T_max]`, °C.
    pub range_c: [f64; 2],
    /// Whether a temperature lay outside the range (allowed by
    /// `allow_extrapolation`).
    pub extrapolated: bool,
    /// How far outside, K (the farthest; 0 within).
    pub extrapolated_k: f64,
    /// The standard uncertainty of the thermometer the model names, K:
    /// the coefficients' standard uncertainties at the temperature include
    /// `u_T · |dc/dT|` (absent when the model names none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thermometer_std_c: Option<f64>,
}

/// Where a temperature model of either kind holds: its `T_ref`, its valid
/// range and the thermometer in its budget.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    /// `T_ref`, °C.
    pub reference_c: f64,
    /// `[T_min, T_max]`, °C.
    pub range_c: [f64; 2],
    /// The thermometer's standard uncertainty, K, when one is budgeted.
    pub thermometer_std_c: Option<f64>,
}

impl From<&ThermalModel> for Span {
    fn from(m: &ThermalModel) -> Self {
        Span {
            reference_c: m.reference_c(),
            range_c: m.range_c(),
            thermometer_std_c: m.thermometer_std_c,
        }
    }
}

impl From<&TriadThermalModel> for Span {
    fn from(m: &TriadThermalModel) -> Self {
        Span {
            reference_c: m.reference_c(),
            range_c: m.range_c(),
            thermometer_std_c: None,
        }
    }
}

impl TemperatureUsed {
    /// A model spanning `span` read at `temperatures`.
    pub fn of(span: impl Into<Span>, temperatures: Temperatures) -> Self {
        let span = span.into();
        let [lo, hi] = span.range_c;
        let outside = temperatures
            .values()
            .iter()
            .map(|(_, t)| (lo - t).max(t - hi).max(0.0))
            .fold(0.0, f64::max);
        TemperatureUsed {
            temperature_c: temperatures,
            reference_c: span.reference_c,
            range_c: [lo, hi],
            extrapolated: outside > 0.0,
            extrapolated_k: outside,
            thermometer_std_c: span.thermometer_std_c,
        }
    }
}

/// Why a temperature given for calibration `id`, which has no temperature
/// model, is refused.
pub fn no_model(id: Uuid) -> String {
    format!(
        "calibration {id} has no temperature model: its coefficients hold at the temperature it \
         was performed at; omit temperature_c (a model over temperature is stored with POST \
         /v1/calibrations/thermal)"
    )
}

/// Why `t` is refused: `outside` K outside the range of a model spanning
/// `span`, for calibration `id`.
pub fn outside_range(t: f64, outside: f64, span: impl Into<Span>, id: Uuid) -> String {
    let [lo, hi] = span.into().range_c;
    format!(
        "is {t} °C, {outside:.3} K outside the range of calibration {id}'s temperature model \
         ({lo:.2} to {hi:.2} °C, its set points' span); allow_extrapolation: true uses its \
         polynomials there"
    )
}

impl CompensateRequest {
    /// The input acceleration for every output with the temperature model
    /// `model` of calibration `id`, each output's coefficients evaluated
    /// at its temperature; and the temperature used.
    pub fn compensate_at(
        &self,
        model: &ThermalModel,
        id: Uuid,
    ) -> Result<(Vec<f64>, TemperatureUsed), Invalid> {
        let root = Loc::Root;
        let [lo, hi] = model.range_c();
        let Some(temperatures) = &self.temperature_c else {
            return Err(Invalid::one(
                root.key("temperature_c"),
                format!(
                    "is required: calibration {id} is a temperature model, valid from {lo:.2} to \
                     {hi:.2} °C; give the sensor's temperature, one for every output or one per \
                     output"
                ),
            ));
        };
        let Outputs::Axis(outputs) = &self.outputs else {
            return Err(Invalid::one(
                root.key("outputs"),
                format!(
                    "calibration {id} is of a single-axis sensor: give one number per output, \
                     not triples"
                ),
            ));
        };
        let mut errors = Errors::default();
        for (at, t) in temperatures.values() {
            let outside = (lo - t).max(t - hi).max(0.0);
            if outside > 0.0 && !self.allow_extrapolation {
                errors.add(at, outside_range(t, outside, model, id));
            }
        }
        errors.finish(|| ())?;
        let mut errors = Errors::default();
        // One compensator per distinct temperature.
        let mut by_temperature: HashMap<u64, Result<Compensator, String>> = HashMap::new();
        let outputs_at = root.key("outputs");
        let mut a_i = Vec::with_capacity(outputs.len());
        for (k, u) in outputs.iter().enumerate() {
            let t = temperatures.of(k);
            let comp = by_temperature.entry(t.to_bits()).or_insert_with(|| {
                Compensator::new(&model.at(t).coefficients).map_err(|e| e.to_string())
            });
            let ap = self.a_p.as_ref().map_or(0.0, |v| v[k]);
            let ao = self.a_o.as_ref().map_or(0.0, |v| v[k]);
            match comp {
                Ok(c) => a_i.push(c.input(*u, ap, ao).unwrap_or_else(|e| {
                    errors.add(outputs_at.index(k), e.to_string());
                    0.0
                })),
                Err(e) => {
                    errors.add(
                        temperatures.at(k),
                        format!("calibration {id}'s coefficients at {t} °C cannot be used: {e}"),
                    );
                    a_i.push(0.0);
                }
            }
        }
        let a_i = errors.finish(|| a_i)?;
        Ok((a_i, TemperatureUsed::of(model, temperatures.clone())))
    }
}

impl CompensateRequest {
    /// The specific force `g = S(T)⁻¹ (u − b(T))` for every triple of
    /// outputs with the triad's temperature model `model` of calibration
    /// `id`, each output's `b` and `S` evaluated at its temperature; and the
    /// temperature used.
    pub fn compensate_triad_at(
        &self,
        model: &TriadThermalModel,
        id: Uuid,
    ) -> Result<(Vec<[f64; 3]>, TemperatureUsed), Invalid> {
        let root = Loc::Root;
        let [lo, hi] = model.range_c();
        let Some(temperatures) = &self.temperature_c else {
            return Err(Invalid::one(
                root.key("temperature_c"),
                format!(
                    "is required: calibration {id} is a triad's temperature model, valid from \
                     {lo:.2} to {hi:.2} °C; give the triad's temperature, one for every output \
                     or one per output"
                ),
            ));
        };
        let Outputs::Triad(outputs) = &self.outputs else {
            return Err(Invalid::one(
                root.key("outputs"),
                format!(
                    "calibration {id} is a triad's: give each output as a triple [u_x, u_y, u_z]"
                ),
            ));
        };
        let mut errors = Errors::default();
        for (at, t) in temperatures.values() {
            let outside = (lo - t).max(t - hi).max(0.0);
            if outside > 0.0 && !self.allow_extrapolation {
                errors.add(at, outside_range(t, outside, model, id));
            }
        }
        errors.finish(|| ())?;
        let mut errors = Errors::default();
        // One triad per distinct temperature.
        let mut by_temperature: HashMap<u64, Triad> = HashMap::new();
        let outputs_at = root.key("outputs");
        let mut g = Vec::with_capacity(outputs.len());
        for (k, u) in outputs.iter().enumerate() {
            let t = temperatures.of(k);
            let triad = by_temperature.entry(t.to_bits()).or_insert_with(|| {
                let at = model.at(t);
                Triad::linear(at.b, at.s)
            });
            g.push(triad.compensate(*u).unwrap_or_else(|e| {
                errors.add(
                    outputs_at.index(k),
                    format!("calibration {id} at {t} °C cannot compensate it: {e}"),
                );
                [0.0; 3]
            }));
        }
        let g = errors.finish(|| g)?;
        Ok((g, TemperatureUsed::of(model, temperatures.clone())))
    }
}
