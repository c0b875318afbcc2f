//! Coefficients over temperature (issue 45): a single axis's submission
//! whose runs were made at several temperatures, read, checked and
//! identified set point by set point on the compute pool, and each
//! coefficient's polynomial fitted ([`crate::domain::thermal`]) — answered
//! (`identify`), or stored as the thermal calibration kind (`assess`): one
//! calibration of its sensor whose coefficients are the model at `T_ref`
//! and whose temperature model is kept beside them, for the coefficients
//! and compensation at a temperature. A triad's `b` and `S` likewise, not
//! stored yet.
//!
//! **From stored calibrations.** A JSON body naming stored single-axis
//! calibrations of the sensor (`calibrations`: their ids) is read by
//! [`combined`]: their stored submissions make one, fitted as one sent
//! whole; the body is what is stored, and the model names them
//! (`from_calibrations`).
//!
//! **Standards.** The stand, thermometer and gravity value a submission
//! names are resolved as a single axis's are ([`resolve_standards`]): in
//! calibration and in service when the test was performed, recorded as
//! used (so that a nonconformity of one holds the model), and a
//! nonconformity's window holding the test holds it as stored. The
//! thermometer's `temperature_std_c` enters the model's budget at every
//! temperature it is read at (`u_T · |dc/dT|`,
//! [`ThermalModel::read`](crate::domain::thermal::ThermalModel::read)).
//! The stand's indexing error and the gravity value's uncertainty are not
//! carried into the polynomials: the model states no expanded uncertainty
//! of the single-axis budget's kind.

use accelcal_core::TermMap;
use bytes::Bytes;
use serde::Serialize;
use uuid::Uuid;

mod combined;
pub mod triad;

use super::single_axis::{resolve_standards, roles};
use super::standards::Resolved;
use super::subject::{in_force, station};
use super::{Assessed, Error, Lab, Upload};
use crate::domain::auth::Principal;
use crate::domain::field::Loc;
use crate::domain::nonconformity::HeldBy;
use crate::domain::review::Supersedes;
use crate::domain::standards::UsedStandard;
use crate::domain::submission::{Media, Submission, evaluate, performed_when};
use crate::domain::thermal::combine::FromCalibrations;
use crate::domain::thermal::decision::{ThermalDecision, decide_model};
use crate::domain::thermal::{Fit, ThermalModel, TriadThermalModel, model};
use crate::domain::timestamp::Timestamp;
use crate::store::NewCalibration;

/// A stored temperature model's result document (`POST
/// /v1/calibrations/thermal`, and `GET /v1/calibrations/{id}` for one).
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct StoredThermal {
    /// `thermal`.
    pub kind: &'static str,
    /// The calibration's id.
    pub id: Uuid,
    /// The sensor.
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
    /// `T_ref`, °C: where `coefficients` hold.
    pub reference_c: f64,
    /// The valid range `[T_min, T_max]`, °C.
    pub range_c: [f64; 2],
    /// Every coefficient at `T_ref` (`a_0`): what history, stability and
    /// the coefficients without a temperature serve.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    pub coefficients: TermMap<f64>,
    /// Their standard uncertainties.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    pub std_errors: TermMap<f64>,
    /// The sensor type it was judged by, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensor_type: Option<String>,
    /// Its judgement against that type's limits: every limited coefficient
    /// at every set point and across the range, its worst stated.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub decision: Option<ThermalDecision>,
    /// When the sensor is next due: a judged model's performance date plus
    /// its type's interval.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub due_at: Option<Timestamp>,
    /// What its expanded uncertainties hold fixed — the sensor type's
    /// coverage probability or factor, 95.45 % without one — for the
    /// decision and the certificate's `a_d` alike.
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
    /// The stored calibrations it was fitted from, in the order named
    /// (absent for runs sent whole).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub from_calibrations: Vec<Uuid>,
    /// The model: the set points and every coefficient's polynomial (with
    /// the thermometer's standard uncertainty, when one was named).
    #[schema(value_type = Object)]
    pub thermal: ThermalModel,
}

/// A model's input read: the submission fitted, the station (checked
/// against the token's) and the calibrations it was combined from (none
/// for runs sent whole).
struct Read {
    sub: Submission,
    station_id: Option<String>,
    from: Vec<Uuid>,
    thermal: ThermalModel,
}

/// What the compute pool makes of a model's body first: runs sent whole,
/// evaluated and fitted; or a body naming stored calibrations.
enum First {
    Whole(Box<Submission>, Option<String>, Box<ThermalModel>),
    Named(Bytes),
}

/// `upload` read for `principal` at `received_at` and fitted with `fit`:
/// runs sent whole (evaluated and fitted in one pass on the compute pool,
/// then their standards resolved), or a JSON body naming stored
/// calibrations ([`combined::read`]); the thermometer's uncertainty kept
/// in the model.
async fn read(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    received_at: Timestamp,
    fit: Fit,
) -> Result<Read, Error> {
    let size = upload.bytes.len();
    let who = principal.clone();
    let first = lab
        .compute_for(size, move || {
            let e = match body(upload, |u| evaluate(u.media, &u.bytes, received_at))? {
                Body::Whole(e) => e,
                Body::Named(bytes) => return Ok(First::Named(bytes)),
            };
            let station_id = station(&who, e.submission.station_id.as_deref())?;
            let thermal = model(&e.submission, &fit)?;
            // The whole submission's own identification is dropped here,
            // on the thread that made it (freed elsewhere it costs a
            // tenth of the route's CPU).
            Ok::<_, Error>(First::Whole(
                Box::new(e.submission),
                station_id,
                Box::new(thermal),
            ))
        })
        .await??;
    let (sub, station_id, from, mut thermal) = match first {
        First::Whole(mut sub, station_id, thermal) => {
            let performed_at = sub.performed_at.unwrap_or(received_at);
            resolve_standards(lab, &mut sub, performed_at).await?;
            (*sub, station_id, Vec::new(), *thermal)
        }
        First::Named(bytes) => named(lab, principal, &bytes, fit).await?,
    };
    thermal.thermometer_std_c = thermometer(&sub.standards_used);
    Ok(Read {
        sub,
        station_id,
        from,
        thermal,
    })
}

/// The JSON body `json` naming stored calibrations, read for `principal`
/// ([`combined::read`]) and fitted with `fit` on the compute pool: the
/// submission they make, the station, their ids and the model.
async fn named(
    lab: &Lab,
    principal: &Principal,
    json: &[u8],
    fit: Fit,
) -> Result<(Submission, Option<String>, Vec<Uuid>, ThermalModel), Error> {
    let (sub, station_id, from) = combined::read(lab, principal, json).await?;
    let (sub, thermal) = lab
        .compute_for(json.len(), move || {
            let thermal = model(&sub, &fit)?;
            Ok::<_, Error>((sub, thermal))
        })
        .await??;
    Ok((sub, station_id, from, thermal))
}

/// The temperature model of `upload` for `principal`, its runs grouped
/// within `tolerance_k` and each polynomial fitted with `options`
/// (`crate::domain::thermal::ThermalParams::checked`), the standards it
/// names resolved (module doc). A sensor type is refused rather than
/// ignored: a model is judged when it is stored.
pub async fn identify(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    fit: Fit,
) -> Result<ThermalModel, Error> {
    let refuse_type = || {
        Error::invalid(
            Loc::Root.key("sensor_type"),
            "a sensor type judges a temperature model when it is stored (POST \
             /v1/calibrations/thermal): omit it here",
        )
    };
    let now = Timestamp::now();
    let who = principal.clone();
    // Runs sent whole are fitted in one pass on the compute pool, and only
    // the model and the standards named leave it (the submission freed
    // where it was made: freed elsewhere it costs a tenth of the route's
    // CPU); a body naming calibrations is read as [`read`] reads it.
    let whole = lab
        .compute_for(upload.bytes.len(), move || {
            let e = match body(upload, |u| evaluate(u.media, &u.bytes, now))? {
                Body::Whole(e) => e,
                Body::Named(bytes) => return Ok(Err(bytes)),
            };
            station(&who, e.submission.station_id.as_deref())?;
            if e.submission.sensor_type.is_some() {
                return Err(refuse_type());
            }
            let thermal = model(&e.submission, &fit)?;
            let performed_at = e.submission.performed_at.unwrap_or(now);
            Ok::<_, Error>(Ok((thermal, e.submission.standards, performed_at)))
        })
        .await??;
    match whole {
        Ok((mut thermal, named, performed_at)) => {
            if let Some(named) = named {
                let used = super::standards::resolve(lab, &roles(&named), performed_at).await?;
                thermal.thermometer_std_c = thermometer(&used.used);
            }
            Ok(thermal)
        }
        Err(json) => {
            let (sub, _, _, mut thermal) = named(lab, principal, &json, fit).await?;
            thermal.thermometer_std_c = thermometer(&sub.standards_used);
            Ok(thermal)
        }
    }
}

/// A temperature model's body: runs (or a triad's readings) sent whole,
/// or a JSON body naming stored calibrations, by its bytes.
enum Body<T> {
    Whole(T),
    Named(Bytes),
}

/// `upload` read by `whole` (on the compute pool's thread); only a body
/// that is not one is looked at for `calibrations` — a second parse of
/// every body would cost a fit route a sixth of its throughput — and
/// otherwise refused as `whole` refused it.
fn body<T, E: Into<Error>>(
    upload: Upload,
    whole: impl FnOnce(&Upload) -> Result<T, E>,
) -> Result<Body<T>, Error> {
    match whole(&upload) {
        Ok(t) => Ok(Body::Whole(t)),
        Err(_) if upload.media == Media::Json && FromCalibrations::named(&upload.bytes) => {
            Ok(Body::Named(upload.bytes))
        }
        Err(refused) => Err(refused.into()),
    }
}

/// The largest standard uncertainty of the thermometers among `used`, if
/// any was named (a model combined from calibrations may have several).
pub(super) fn thermometer(used: &[UsedStandard]) -> Option<f64> {
    used.iter()
        .filter(|u| u.role == "thermometer")
        .filter_map(|u| u.parameters.temperature_std_c)
        .reduce(f64::max)
}

/// The temperature model of the triad `upload` for `principal` fitted
/// with `fit` (its parameters kept in it), the standards it names
/// resolved — a thermometer's uncertainty enters its elements — as for a
/// single axis; or of the stored triads a JSON body names
/// ([`triad::named`]). A sensor type is refused rather than ignored: a
/// model is judged when it is stored.
pub async fn identify_triad(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    fit: Fit,
) -> Result<TriadThermalModel, Error> {
    let now = Timestamp::now();
    // A body sent whole is fitted on the compute pool and only the model
    // and the standards named leave it (the submission freed where it was
    // made, as a single axis's).
    let whole = lab
        .compute_for(upload.bytes.len(), move || {
            let sub = match body(upload, super::triad::read)? {
                Body::Whole(sub) => sub,
                Body::Named(bytes) => return Ok(Err(bytes)),
            };
            if sub.sensor_type.is_some() {
                return Err(Error::invalid(
                    Loc::Root.key("sensor_type"),
                    "a sensor type judges a triad's temperature model when it is stored (POST \
                     /v1/calibrations/thermal/triad): omit it here",
                ));
            }
            let performed_at = match sub.performed_at {
                None => now,
                Some(t) => performed_when(t, now)
                    .map_err(|why| Error::invalid(Loc::Root.key("performed_at"), why))?,
            };
            let (sub, model) = triad::fitted(sub, fit)?;
            Ok::<_, Error>(Ok((model, sub.standards, performed_at)))
        })
        .await??;
    match whole {
        Ok((mut model, named, performed_at)) => {
            if !named.is_empty() {
                let roles: Vec<(&str, Option<String>)> = named
                    .into_iter()
                    .map(|(role, id)| (role, Some(id)))
                    .collect();
                let used = super::standards::resolve(lab, &roles, performed_at).await?;
                model.thermometer_std_c = thermometer(&used.used);
            }
            Ok(model)
        }
        Err(json) => {
            let read = triad::named(lab, principal, &json, fit).await?;
            let mut model = read.thermal;
            model.thermometer_std_c = thermometer(read.named.as_deref().unwrap_or_default());
            Ok(model)
        }
    }
}

/// `upload` assessed as a temperature model fitted with `fit`, to be
/// stored under `id` (with `supersedes`, the calibration it corrects):
/// read and fitted on the compute pool, its standards resolved (module
/// doc), and judged by the sensor type in force (named, or the sensor's)
/// at every set point and across the range ([`decide_model`]).
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
        sub,
        station_id,
        from,
        thermal,
    } = read(lab, principal, upload, received_at, fit).await?;
    let performed_at = sub.performed_at.unwrap_or(received_at);
    let subject = in_force(
        lab,
        principal,
        &sub.sensor_id,
        sub.sensor_type.as_ref(),
        false,
        received_at,
    )
    .await?;
    let decision = match &subject.sensor_type {
        None => None,
        Some(t) => Some(judged(&thermal, t, &sub.unit)?),
    };
    let due_at = subject
        .sensor_type
        .as_ref()
        .filter(|_| decision.is_some())
        .map(|t| performed_at.plus_seconds(i64::from(t.interval_days) * 86_400));
    let at_reference = thermal.at(thermal.reference_c());
    let view = StoredThermal {
        kind: "thermal",
        id,
        sensor_id: sub.sensor_id.clone(),
        station_id: station_id.clone(),
        performed_at,
        received_at,
        supersedes,
        unit: sub.unit.clone(),
        runs: sub.test.runs().len(),
        reference_c: thermal.reference_c(),
        range_c: thermal.range_c(),
        coefficients: at_reference.coefficients.clone(),
        std_errors: at_reference.std_errors.clone(),
        sensor_type: subject.sensor_type.as_ref().map(|t| t.type_id.clone()),
        decision,
        due_at,
        coverage: crate::domain::sensor_types::coverage(subject.sensor_type.as_ref()),
        standards: sub.standards_used.clone(),
        held_by: sub.held_by.clone(),
        from_calibrations: from,
        thermal,
    };
    let result = Bytes::from(serde_json::to_vec(&view).map_err(|err| {
        tracing::error!(error = %err, "a temperature model's result did not serialise");
        Error::Internal
    })?);
    let record = NewCalibration {
        id,
        sensor_id: view.sensor_id.clone(),
        station_id,
        performed_at,
        received_at,
        unit: view.unit.clone(),
        model: sub.test.model().clone(),
        runs: view.runs,
        coefficients: view.coefficients,
        std_errors: view.std_errors,
        result: result.clone(),
        submission,
        content_type,
        submitted_by: principal.id.clone(),
        sensor_type: view.sensor_type,
        assigns_type: sub.sensor_type.is_some(),
        verdict: view.decision.map(|d| d.verdict),
        due_at,
        expanded: None,
        triad: None,
        standards: Resolved::uses(&view.standards),
        fitted_from: view.from_calibrations.clone(),
        thermal: Some(Box::new(view.thermal)),
        thermal_triad: None,
    };
    Ok(Assessed {
        sensor_id: record.sensor_id.clone(),
        result,
        record: Some(record),
    })
}

/// `thermal` judged by sensor type `t`, whose limits are in the outputs'
/// unit `unit`.
fn judged(
    thermal: &ThermalModel,
    t: &crate::domain::sensor_types::SensorType,
    unit: &str,
) -> Result<ThermalDecision, Error> {
    if let Some(refused) = t.unit_refusal(unit) {
        return Err(refused.into());
    }
    decide_model(thermal, t.decision_rule, &t.limits, t.coverage())
        .map_err(|term| t.missing_term(term).into())
}
