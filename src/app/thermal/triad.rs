//! A triad's temperature model stored as a calibration (issue 45 items 1,
//! 4 and 6), `POST /v1/calibrations/thermal/triad`: the triad body with
//! known orientations, every run with its temperature, fitted as
//! `POST /v1/identify/thermal/triad` fits it, and stored as one
//! calibration of the triad whose elements are the model at `T_ref`
//! (`b = a_0` of each element's polynomial, `S` likewise, `T = S⁻¹`):
//! history, stability and the coefficients without a temperature serve
//! those; the coefficients and compensation at a temperature evaluate the
//! model. What a stored triad settles first is settled alike
//! ([`super::super::triad::preamble`]): the sensor type in force and the
//! standards named — a thermometer's uncertainty enters every element read
//! at a temperature, a nonconformity of any holds the model. The type
//! judges every limited element at every set point and across the range
//! ([`decide_triad_model`]), its coverage the certificate's.

use accelcal_core::{Model, Term};
use bytes::Bytes;
use serde::Serialize;
use uuid::Uuid;

use super::super::standards::Resolved;
use super::super::triad::{Preamble, preamble};
use super::super::{Assessed, Error, Lab, Upload};
use super::{combined, thermometer};
use crate::domain::auth::Principal;
use crate::domain::field::Loc;
use crate::domain::nonconformity::HeldBy;
use crate::domain::review::Supersedes;
use crate::domain::sensor_types::SensorType;
use crate::domain::standards::UsedStandard;
use crate::domain::thermal::decision::{TriadThermalDecision, decide_triad_model};
use crate::domain::thermal::{Fit, TriadThermalModel, triad_model};
use crate::domain::timestamp::Timestamp;
use crate::domain::triad::TriadSubmission;
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
    /// The runs submitted (the static positions, of a model from the
    /// gravity magnitude).
    pub runs: usize,
    /// `T_ref`, °C: where `b`, `S` and `T` hold.
    pub reference_c: f64,
    /// The valid range `[T_min, T_max]`, °C.
    pub range_c: [f64; 2],
    /// Its elements at `T_ref` (`b`, `S`, `T = S⁻¹`, with the standard
    /// uncertainties of `b` and `S`): what history, stability and the
    /// coefficients without a temperature serve.
    pub elements: TriadElements,
    /// The sensor type it was judged by, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensor_type: Option<String>,
    /// Its judgement against that type's limits: every limited element at
    /// every set point and across the range, its worst stated.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub decision: Option<TriadThermalDecision>,
    /// When the triad is next due: a judged model's performance date plus
    /// its type's interval.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub due_at: Option<Timestamp>,
    /// What its expanded uncertainties hold fixed — the sensor type's
    /// coverage probability or factor, 95.45 % without one.
    #[schema(value_type = Object)]
    pub coverage: accelcal_core::coverage::Coverage,
    /// The reference standards used, with the certificates in force.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub standards: Vec<UsedStandard>,
    /// The nonconformities of those standards in whose windows the test
    /// was performed: the model was stored held.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    #[schema(value_type = Vec<Object>)]
    pub held_by: Vec<HeldBy>,
    /// The stored triad calibrations it was fitted from, in the order
    /// named (absent for runs sent whole).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub from_calibrations: Vec<Uuid>,
    /// The model: the set points and every element's polynomial (with the
    /// thermometer's standard uncertainty, when one was named).
    #[schema(value_type = Object)]
    pub thermal: TriadThermalModel,
}

/// A triad model's body read and fitted: the submission fitted, the
/// standards its named calibrations used (`None` for a body sent whole,
/// whose standards are named in it), their ids and the model.
pub(super) struct Read {
    pub sub: TriadSubmission,
    pub named: Option<Vec<UsedStandard>>,
    pub from: Vec<Uuid>,
    pub thermal: TriadThermalModel,
}

/// `upload` read for `principal` and fitted with `fit` (its parameters
/// kept in the model): a triad body sent whole, read and fitted in one
/// pass on the compute pool; or a JSON body naming stored triads
/// ([`named`]).
async fn read(lab: &Lab, principal: &Principal, upload: Upload, fit: Fit) -> Result<Read, Error> {
    let first = lab
        .compute_for(upload.bytes.len(), move || {
            match super::body(upload, super::super::triad::read)? {
                super::Body::Whole(sub) => fitted(sub, fit).map(Ok),
                super::Body::Named(bytes) => Ok(Err(bytes)),
            }
        })
        .await??;
    match first {
        Ok((sub, thermal)) => Ok(Read {
            sub,
            named: None,
            from: Vec::new(),
            thermal,
        }),
        Err(json) => named(lab, principal, &json, fit).await,
    }
}

/// The JSON body `json` naming stored triads, read for `principal`
/// ([`combined::read_triads`]) and fitted with `fit` on the compute pool.
pub(super) async fn named(
    lab: &Lab,
    principal: &Principal,
    json: &[u8],
    fit: Fit,
) -> Result<Read, Error> {
    let (sub, standards, _, from) = combined::read_triads(lab, principal, json).await?;
    let (sub, thermal) = lab
        .compute_for(json.len(), move || fitted(sub, fit))
        .await??;
    Ok(Read {
        sub,
        named: Some(standards),
        from,
        thermal,
    })
}

/// `sub`'s model fitted with `fit`, its parameters kept in it.
pub(super) fn fitted(
    sub: TriadSubmission,
    fit: Fit,
) -> Result<(TriadSubmission, TriadThermalModel), Error> {
    let mut thermal = triad_model(&sub, fit.tolerance_k, &fit.options)?;
    thermal.fitted_with = fit.params;
    Ok((sub, thermal))
}

/// The elements of `model` at `temperature_c` as a triad's are stored:
/// `b`, `S` with their standard uncertainties and `T = S⁻¹` (refused when
/// `S` is singular there).
pub fn elements_at(model: &TriadThermalModel, temperature_c: f64) -> Option<TriadElements> {
    let at = model.at(temperature_c);
    let triad = accelcal_core::triad::Triad::linear(at.b, at.s);
    let t = crate::domain::triad::invert(&triad)?;
    Some(TriadElements {
        method: model.method.clone(),
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
    let Read {
        mut sub,
        named,
        from,
        mut thermal,
    } = read(lab, principal, upload, fit).await?;
    let Preamble {
        sensor_id,
        station_id,
        performed_at,
        subject,
        mut used,
        held_by,
    } = preamble(
        lab,
        principal,
        &mut sub,
        received_at,
        "to store a triad's model (POST /v1/identify/thermal/triad fits one without)",
    )
    .await?;
    if let Some(named) = named {
        used = named;
    }
    thermal.thermometer_std_c = thermometer(&used);
    let sensor_type = subject.sensor_type;
    let decision = match &sensor_type {
        Some(t) if !t.limits.is_empty() => Some(judged(&thermal, t)?),
        _ => None,
    };
    let due_at = sensor_type
        .as_ref()
        .filter(|_| decision.is_some())
        .map(|t| performed_at.plus_seconds(i64::from(t.interval_days) * 86_400));
    let root = Loc::Root;
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
        sensor_type: sensor_type.as_ref().map(|t| t.type_id.clone()),
        decision,
        due_at,
        coverage: crate::domain::sensor_types::coverage(sensor_type.as_ref()),
        standards: used,
        held_by,
        from_calibrations: from,
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
        sensor_type: view.sensor_type,
        assigns_type: sub.sensor_type.is_some(),
        verdict: view.decision.map(|d| d.verdict),
        due_at,
        expanded: None,
        standards: Resolved::uses(&view.standards),
        fitted_from: view.from_calibrations.clone(),
        triad: Some(Box::new(view.elements)),
        thermal: None,
        thermal_triad: Some(Box::new(view.thermal)),
    };
    Ok(Assessed {
        sensor_id,
        result,
        record: Some(record),
    })
}

/// `thermal` judged by sensor type `t` ([`decide_triad_model`]); a limit
/// on a term no axis models over temperature is refused, naming the type.
fn judged(thermal: &TriadThermalModel, t: &SensorType) -> Result<TriadThermalDecision, Error> {
    decide_triad_model(thermal, t.decision_rule, &t.limits, t.coverage()).map_err(|term| {
        Error::invalid(
            Loc::Root.key("sensor_type"),
            format!(
                "sensor type `{}` sets limits on `{term}`, which a triad's temperature model \
                 does not model (each axis's k0, ki, kp, ko over temperature: b and S)",
                t.type_id
            ),
        )
    })
}
