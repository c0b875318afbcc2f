//! The metrology of one calibration, assembled from the core's pieces with
//! what the store knows: the sensor type in force and the previous
//! calibration. Pure: the caller looks those up.

use accelcal_core::TermMap;
use accelcal_core::adequacy::model_uncertainty;
use accelcal_core::decision::{Decision, decide};
use accelcal_core::history::{PositionError, as_found};
use accelcal_core::quality::{Quality, assess};
use accelcal_core::temperature::{Sensitivity, sensitivity};
use accelcal_core::uncertainty::{Stand, Uncertainty, budget};
use serde::Serialize;
use uuid::Uuid;

use super::field::{Invalid, Loc};
use super::sensor_types::{SensorType, coverage};
use super::submission::{Evaluated, StandIn};
use super::timestamp::Timestamp;

/// The sensor's previous calibration, as far as as-found needs it.
#[derive(Debug, Clone)]
pub struct Previous {
    /// Its id.
    pub id: Uuid,
    /// Its output unit.
    pub unit: String,
    /// Its fused coefficients.
    pub coefficients: TermMap<f64>,
}

/// How far the sensor had drifted since its previous calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AsFoundView {
    /// The previous calibration (the latest earlier `performed_at`).
    pub previous_calibration_id: Uuid,
    /// Per position, in position order.
    pub positions: Vec<PositionError>,
    /// The largest `|error_g|`.
    pub max_abs_error_g: f64,
}

/// What a lab signs beside the coefficients.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrology {
    /// The uncertainty budget of every fused coefficient.
    pub uncertainty: Uncertainty,
    /// The decision against the sensor type's limits; none when untyped.
    pub decision: Option<Decision>,
    /// As found against the previous calibration, when there is one in the
    /// same unit with a scale factor.
    pub as_found: Option<AsFoundView>,
    /// Why `as_found` is null although there is a previous calibration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub as_found_note: Option<String>,
    /// When the sensor is due again (typed sensors).
    pub due_at: Option<Timestamp>,
    /// Temperature sensitivity, when the runs were made at two or more
    /// temperatures.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature: Option<TermMap<Sensitivity>>,
    /// Warnings that never change a number.
    pub quality: Quality,
}

/// The metrology of `e`, performed at `performed_at`, for the sensor type in
/// force and the previous calibration.
pub fn assess_calibration(
    e: &Evaluated,
    performed_at: Timestamp,
    sensor_type: Option<&SensorType>,
    previous: Option<&Previous>,
) -> Result<Metrology, Invalid> {
    let s = &e.submission;
    let cal = &e.calibration;
    let stand = s.stand.as_ref().map_or(Stand::default(), StandIn::core);
    if let Some(refused) = sensor_type.and_then(|t| t.unit_refusal(&s.unit)) {
        return Err(refused);
    }
    let quality = assess(&s.test, cal);
    let uncertainty = budget(
        &s.test,
        &cal.fused.coefficients,
        (&cal.fused.std_errors, &cal.fused.dof),
        stand,
        coverage(sensor_type),
        &model_uncertainty(&s.test, &quality.lack_of_fit),
    )
    .map_err(|err| Invalid::one(Loc::Root.key("stand"), err.to_string()))?;
    let decision = sensor_type
        .map(|t| {
            decide(
                t.decision_rule,
                &t.limits,
                &cal.fused.coefficients,
                &uncertainty.expanded(),
            )
            .map_err(|term| t.missing_term(term))
        })
        .transpose()?;
    let (as_found, as_found_note) = match previous {
        None => (None, None),
        Some(p) if p.unit != s.unit => (
            None,
            Some(format!(
                "the previous calibration {} is in `{}`, this one in `{}`: as found compares \
                 outputs in one unit",
                p.id, p.unit, s.unit
            )),
        ),
        Some(p) => match as_found(&s.test, &p.coefficients) {
            Some(a) => (
                Some(AsFoundView {
                    previous_calibration_id: p.id,
                    positions: a.positions,
                    max_abs_error_g: a.max_abs_error_g,
                }),
                None,
            ),
            None => (
                None,
                Some(format!(
                    "the previous calibration {} has no `ki` to express the errors in g",
                    p.id
                )),
            ),
        },
    };
    let due_at =
        sensor_type.map(|t| performed_at.plus_seconds(i64::from(t.interval_days) * 86_400));
    let temperature = s
        .temperatures_c
        .as_ref()
        .and_then(|t| sensitivity(&cal.runs, t));
    Ok(Metrology {
        uncertainty,
        decision,
        as_found,
        as_found_note,
        due_at,
        temperature,
        quality,
    })
}
