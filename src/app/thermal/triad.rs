//! A triad's temperature model stored as a calibration (issue 45 items 1
//! and 6), `POST /v1/calibrations/thermal/triad`: the triad body with
//! known orientations, every run with its temperature, fitted as
//! `POST /v1/identify/thermal/triad` fits it, and stored as one
//! calibration of the triad whose elements are the model at `T_ref`
//! (`b = a_0` of each element's polynomial, `S` likewise, `T = S⁻¹`):
//! history, stability and the coefficients without a temperature serve
//! those; the coefficients and compensation at a temperature evaluate the
//! model. Not applied yet, and refused rather than ignored: a sensor
//! type's judgement (the body's, or one the sensor has) and reference
//! standards; its certificate is not issued yet.

use accelcal_core::{Model, Term};
use bytes::Bytes;
use serde::Serialize;
use uuid::Uuid;

use super::super::subject::{in_force, station};
use super::super::{Assessed, Error, Lab, Upload};
use super::not_yet;
use crate::domain::auth::Principal;
use crate::domain::field::Loc;
use crate::domain::review::Supersedes;
use crate::domain::submission::performed_when;
use crate::domain::thermal::{Fit, TriadThermalModel, triad_model};
use crate::domain::timestamp::Timestamp;
use crate::domain::triad::KNOWN_ORIENTATIONS;
use crate::store::{NewCalibration, TriadElements};

/// A stored triad's temperature model's result document (`POST
/// /v1/calibrations/thermal/triad`, and `GET /v1/calibrations/{id}` for
/// one).
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct StoredThermalTriad {
    /// `thermal_triad`.
    pub kind: &'static str,
    /// The calibration's id.
    pub id: Uuid,
    /// The triad.
    pub sensor_id: String,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// The calibration this one supersedes, and why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub supersedes: Option<Supersedes>,
    /// The outputs' unit.
    pub unit: String,
    /// The runs submitted.
    pub runs: usize,
    /// `T_ref`, °C: where `b`, `S` and `T` hold.
    pub reference_c: f64,
    /// The valid range `[T_min, T_max]`, °C.
    pub range_c: [f64; 2],
    /// Its elements at `T_ref` (`b`, `S`, `T = S⁻¹`, with the standard
    /// uncertainties of `b` and `S`): what history, stability and the
    /// coefficients without a temperature serve.
    pub elements: TriadElements,
    /// The model: the set points and every element's polynomial.
    #[schema(value_type = Object)]
    pub thermal: TriadThermalModel,
}

/// The elements of `model` at `temperature_c` as a triad's are stored:
/// `b`, `S` with their standard uncertainties and `T = S⁻¹` (refused when
/// `S` is singular there).
pub fn elements_at(model: &TriadThermalModel, temperature_c: f64) -> Option<TriadElements> {
    let at = model.at(temperature_c);
    let triad = accelcal_core::triad::Triad::linear(at.b, at.s);
    let t = crate::domain::triad::invert(&triad)?;
    Some(TriadElements {
        method: KNOWN_ORIENTATIONS.to_owned(),
        b: at.b,
        b_std_errors: Some(at.b_std_errors),
        s: at.s,
        s_std_errors: Some(at.s_std_errors),
        t,
        t_std_errors: None,
        b_expanded: None,
        s_expanded: None,
        s2: None,
        s2_std_errors: None,
        s2_expanded: None,
    })
}

/// `upload` assessed as a triad's temperature model fitted with `fit`, to
/// be stored under `id` (with `supersedes`, the calibration it corrects).
pub async fn assess(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    received_at: Timestamp,
    id: Uuid,
    supersedes: Option<Supersedes>,
    fit: Fit,
) -> Result<Assessed, Error> {
    let (submission, content_type) = (upload.bytes.clone(), upload.content_type.clone());
    let (sub, thermal) = lab
        .compute_for(upload.bytes.len(), move || {
            let sub = super::super::triad::read(&upload)?;
            if sub.sensor_type.is_some() {
                return Err(not_yet("sensor_type", "a sensor type's decision"));
            }
            if !sub.standards.is_empty() {
                return Err(not_yet("standards", "the reference standards' budget"));
            }
            let mut thermal = triad_model(&sub, fit.tolerance_k, &fit.options)?;
            thermal.fitted_with = fit.params;
            Ok::<_, Error>((sub, thermal))
        })
        .await??;
    let root = Loc::Root;
    let sensor_id = sub.sensor_id.clone().ok_or_else(|| {
        Error::invalid(
            root.key("sensor_id"),
            "is required to store a triad's model (POST /v1/identify/thermal/triad fits one \
             without)",
        )
    })?;
    let station_id = station(principal, sub.station_id.as_deref())?;
    let performed_at = match sub.performed_at {
        None => received_at,
        Some(t) => performed_when(t, received_at)
            .map_err(|why| Error::invalid(root.key("performed_at"), why))?,
    };
    let subject = in_force(lab, principal, &sensor_id, None, true, received_at).await?;
    if let Some(t) = &subject.sensor_type {
        return Err(Error::invalid(
            root.key("sensor_type"),
            format!(
                "sensor `{sensor_id}` has type `{}`, whose limits a triad's temperature model \
                 is not judged by yet: store the triad at one temperature (POST \
                 /v1/calibrations/triad), or its model for a sensor without a type",
                t.type_id
            ),
        ));
    }
    let elements = elements_at(&thermal, thermal.reference_c()).ok_or_else(|| {
        Error::invalid(
            root.key("runs"),
            "S at T_ref is singular: the model cannot compensate there",
        )
    })?;
    let view = StoredThermalTriad {
        kind: "thermal_triad",
        id,
        sensor_id: sensor_id.clone(),
        station_id: station_id.clone(),
        performed_at,
        received_at,
        supersedes,
        unit: sub.unit.clone(),
        runs: thermal.set_points.iter().map(|s| s.runs.len()).sum(),
        reference_c: thermal.reference_c(),
        range_c: thermal.range_c(),
        elements,
        thermal,
    };
    let result = Bytes::from(serde_json::to_vec(&view).map_err(|err| {
        tracing::error!(error = %err, "a triad's temperature model did not serialise");
        Error::Internal
    })?);
    let record = NewCalibration {
        id,
        sensor_id: sensor_id.clone(),
        station_id,
        performed_at,
        received_at,
        unit: view.unit,
        model: Model::new(vec![Term::K0, Term::Ki, Term::Kp, Term::Ko])
            .map_err(|_| Error::Internal)?,
        runs: view.runs,
        coefficients: accelcal_core::TermMap(Vec::new()),
        std_errors: accelcal_core::TermMap(Vec::new()),
        result: result.clone(),
        submission,
        content_type,
        submitted_by: principal.id.clone(),
        sensor_type: None,
        assigns_type: false,
        verdict: None,
        due_at: None,
        expanded: None,
        triad: Some(view.elements),
        thermal: None,
        thermal_triad: Some(view.thermal),
        standards: Vec::new(),
    };
    Ok(Assessed {
        sensor_id,
        result,
        record: Some(record),
    })
}
