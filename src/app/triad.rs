//! The triad kind (issue 30): a triad body (JSON or CSV) read and checked,
//! computed as it is stored — with the sensor type's coverage factor and
//! decision, the registered standards and as found against the previous
//! triad — and its result document rendered once; stored as one
//! calibration of its sensor, its elements beside the single-axis columns
//! ([`TriadElements`]). What `POST /v1/calibrations/triad`, a correction and
//! a reprocessing of a triad store.

use accelcal_core::gravity_fit::MIN_POSITIONS;
use accelcal_core::{Model, Term, TermMap};
use bytes::Bytes;
use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::standards::{Resolved, resolve};
use super::subject::{Subject, in_force, station};
use super::{Assessed, Error, Lab, Upload};
use crate::domain::auth::Principal;
use crate::domain::field::Loc;
use crate::domain::nonconformity::HeldBy;
use crate::domain::review::Supersedes;
use crate::domain::sensor_types::SensorType;
use crate::domain::standards::UsedStandard;
use crate::domain::submission::{Media, performed_when};
use crate::domain::timestamp::Timestamp;
use crate::domain::triad::{
    Form, GRAVITY_MAGNITUDE, TriadBody, TriadResult, TriadSubmission, as_found, compute,
    decide_triad,
};
use crate::domain::{triad_csv, typed};
use crate::store::{CalibrationSummary, NewCalibration, TriadElements};

/// A stored triad's result document (`POST /v1/calibrations/triad`, and
/// `GET /v1/calibrations/{id}` for a triad): the triad's result with what
/// storing it added.
#[derive(Debug, Serialize, ToSchema)]
pub struct StoredTriad {
    /// The calibration's id.
    pub id: Uuid,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// The calibration this one supersedes, and why (a correction or a
    /// reprocessing).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub supersedes: Option<Supersedes>,
    /// When the sensor is next due: a judged triad's performance date plus
    /// its type's interval.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub due_at: Option<Timestamp>,
    /// The triad.
    #[serde(flatten)]
    pub result: TriadResult,
}

/// Judges `r` against sensor type `t`'s limits ([`decide_triad`]), element
/// by element. A triad from the gravity magnitude is judged on the elements
/// it measures (those zero by the frame convention are not, and the note
/// says so); with exactly nine positions it has no uncertainty and is not
/// judged, saying why.
fn judge(r: &mut TriadResult, t: &SensorType) -> Result<(), Error> {
    if t.limits.is_empty() {
        return Ok(());
    }
    match decide_triad(r, t.decision_rule, &t.limits) {
        Ok(Some(d)) => {
            if r.method == GRAVITY_MAGNITUDE {
                r.decision_note = Some(format!(
                    "S_xy, S_xz and S_yz are zero by the frame convention of a triad found from \
                     the gravity magnitude (the sensor's x axis and xy-plane define the frame): \
                     not measured, so not judged against sensor type `{}`",
                    t.type_id
                ));
            }
            r.decision = Some(d);
        }
        Ok(None) => {
            r.decision_note = Some(format!(
                "not judged against sensor type `{}`: with exactly {MIN_POSITIONS} static \
                 positions the fit from the gravity magnitude has no degree of freedom left, so \
                 no standard error and no uncertainty (hold at least {} orientations)",
                t.type_id,
                MIN_POSITIONS + 1
            ))
        }
        Err(term) => {
            return Err(Error::invalid(
                Loc::Root.key("sensor_type"),
                format!(
                    "sensor type `{}` sets limits on `{term}`, which a triad does not identify \
                     (each axis's k0, ki, kp, ko: b and S)",
                    t.type_id
                ),
            ));
        }
    }
    Ok(())
}

/// As found of `r` against the sensor's previous calibration `p` (a
/// triad's, in the same unit), or why not.
fn found(r: &mut TriadResult, p: &CalibrationSummary) {
    let Some(t) = p.triad.as_ref() else {
        return; // a sensor's calibrations are of one kind: not reached
    };
    if p.unit != r.unit {
        r.as_found_note = Some(format!(
            "the previous calibration {} is in `{}`, this one in `{}`: as found compares \
             outputs in one unit",
            p.id, p.unit, r.unit
        ));
        return;
    }
    r.as_found = as_found(r, p.id, &t.model());
    if r.as_found.is_none() {
        r.as_found_note = Some(format!(
            "the previous calibration {}'s S is singular: it cannot compensate",
            p.id
        ));
    }
}

/// What a triad's result stores of itself.
fn elements(r: &TriadResult) -> TriadElements {
    TriadElements {
        method: r.method.to_owned(),
        b: r.b,
        b_std_errors: r.b_std_errors,
        s: r.s,
        s_std_errors: r.s_std_errors,
        t: r.t,
        t_std_errors: r.t_std_errors,
        b_expanded: r.b_expanded,
        s_expanded: r.s_expanded,
        s2: r.s2,
        s2_std_errors: r.s2_std_errors,
        s2_expanded: r.s2_expanded,
    }
}

/// A triad body read (JSON or CSV) and checked.
pub fn read(upload: &Upload) -> Result<TriadSubmission, Error> {
    let parsed = match upload.media {
        Media::Csv => {
            let text = std::str::from_utf8(&upload.bytes)
                .map_err(|_| Error::Unreadable("the CSV body is not UTF-8".to_owned()))?;
            triad_csv::read(text)?
        }
        Media::Json => typed::from_json::<TriadBody>(&upload.bytes)?,
    };
    Ok(parsed.check()?)
}

/// A triad computed from `upload` and answered, not stored (`POST
/// /v1/identify/triad`): read and computed on the compute pool (a recording
/// may be megabytes); what only a stored triad has — standards resolved
/// from the registry, a sensor type that judges it — is refused rather
/// than ignored.
pub async fn identify(lab: &Lab, upload: Upload) -> Result<TriadResult, Error> {
    lab.compute_for(upload.bytes.len(), move || -> Result<TriadResult, Error> {
        let sub = read(&upload)?;
        let stored_only = |key: &str, what: &str| {
            Error::invalid(
                Loc::Root.key(key),
                format!("{what} only when the triad is stored: POST /v1/calibrations/triad"),
            )
        };
        if !sub.standards.is_empty() {
            return Err(stored_only("standards", "reference standards are resolved"));
        }
        if sub.sensor_type.is_some() {
            return Err(stored_only("sensor_type", "a sensor type judges a triad"));
        }
        Ok(compute(sub)?)
    })
    .await?
}

/// What storing a triad body — a triad's or a triad's temperature model
/// — settles before it is computed: its sensor (required), the station
/// (checked against the token's), when it was performed, the sensor type
/// in force (named, or the sensor's; refused when its limits are in
/// another unit) and the standards it names resolved there (the stand
/// they make set in `sub`).
pub(super) struct Preamble {
    /// The triad.
    pub sensor_id: String,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// The sensor as read, and the type in force.
    pub subject: Subject,
    /// The standards used, with the certificates in force.
    pub used: Vec<UsedStandard>,
    /// The nonconformities that hold the test.
    pub held_by: Vec<HeldBy>,
}

/// The [`Preamble`] of storing `sub` for `principal` at `received_at`;
/// `without` says why a sensor id is required (and where to compute
/// without one).
pub(super) async fn preamble(
    lab: &Lab,
    principal: &Principal,
    sub: &mut TriadSubmission,
    received_at: Timestamp,
    without: &str,
) -> Result<Preamble, Error> {
    let root = Loc::Root;
    let sensor_id = sub
        .sensor_id
        .clone()
        .ok_or_else(|| Error::invalid(root.key("sensor_id"), format!("is required {without}")))?;
    let station_id = station(principal, sub.station_id.as_deref())?;
    let performed_at = match sub.performed_at {
        None => received_at,
        Some(t) => performed_when(t, received_at)
            .map_err(|why| Error::invalid(root.key("performed_at"), why))?,
    };
    let subject = in_force(
        lab,
        principal,
        &sensor_id,
        sub.sensor_type.as_ref(),
        true,
        received_at,
    )
    .await?;
    if let Some(refused) = subject
        .sensor_type
        .as_ref()
        .and_then(|t| t.unit_refusal(&sub.unit))
    {
        return Err(refused.into());
    }
    let (used, held_by) = if sub.standards.is_empty() {
        (Vec::new(), Vec::new())
    } else {
        let roles: Vec<(&str, Option<String>)> = sub
            .standards
            .iter()
            .map(|(role, id)| (*role, Some(id.clone())))
            .collect();
        let r = resolve(lab, &roles, performed_at).await?;
        sub.stand = r.stand.core();
        (r.used, r.held_by)
    };
    Ok(Preamble {
        sensor_id,
        station_id,
        performed_at,
        subject,
        used,
        held_by,
    })
}

/// A triad body computed as it is stored under `id` — checked, with the
/// sensor type in force and its decision, the registered standards and as
/// found against the previous triad — and its result document rendered
/// once; with `supersedes`, the calibration it corrects is recorded in it.
/// What `POST /v1/calibrations/triad`, superseding and reprocessing store.
pub async fn assess(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    received_at: Timestamp,
    id: Uuid,
    supersedes: Option<Supersedes>,
) -> Result<Assessed, Error> {
    let (submission, content_type) = (upload.bytes.clone(), upload.content_type.clone());
    let size = upload.bytes.len();
    let mut sub = lab.compute_for(size, move || read(&upload)).await??;
    let Preamble {
        sensor_id,
        station_id,
        performed_at,
        subject,
        used,
        held_by,
    } = preamble(
        lab,
        principal,
        &mut sub,
        received_at,
        "to store a triad (POST /v1/identify/triad computes one without)",
    )
    .await?;
    let sensor_type = subject.sensor_type.clone();
    let assigns_type = sub.sensor_type.is_some();
    let uses = Resolved::uses(&used);
    let runs = match &sub.form {
        Form::Known { runs, .. } => runs.len(),
        _ => 1,
    };
    let judged_by = sensor_type.clone();
    let previous = subject.previous(lab, performed_at).await?;
    let result = lab
        .compute_for(size, move || -> Result<TriadResult, Error> {
            let mut sub = sub;
            if let Some(t) = &judged_by {
                sub.coverage = t.coverage();
            }
            let mut result = compute(sub)?;
            if let Some(t) = &judged_by {
                judge(&mut result, t)?;
            }
            if let Some(p) = &previous {
                found(&mut result, p);
            }
            result.standards = used;
            result.held_by = held_by;
            Ok(result)
        })
        .await??;
    let due_at = sensor_type
        .as_ref()
        .filter(|_| result.decision.is_some())
        .map(|t| performed_at.plus_seconds(i64::from(t.interval_days) * 86_400));
    let record = NewCalibration {
        id,
        sensor_id: sensor_id.clone(),
        station_id: station_id.clone(),
        performed_at,
        received_at,
        unit: result.unit.clone(),
        model: Model::new(
            [Term::K0, Term::Ki, Term::Kp, Term::Ko]
                .into_iter()
                .chain(result.s2.map(|_| Term::Kii))
                .collect(),
        )
        .map_err(|_| Error::Internal)?,
        runs,
        coefficients: TermMap(Vec::new()),
        std_errors: TermMap(Vec::new()),
        result: Bytes::new(),
        submission,
        content_type,
        submitted_by: principal.id.clone(),
        sensor_type: sensor_type.map(|t| t.type_id),
        assigns_type,
        verdict: result.decision.as_ref().map(|d| d.verdict),
        due_at,
        expanded: None,
        triad: Some(Box::new(elements(&result))),
        thermal: None,
        thermal_triad: None,
        standards: uses,
        fitted_from: Vec::new(),
    };
    let view = StoredTriad {
        id,
        station_id,
        performed_at,
        received_at,
        supersedes,
        due_at,
        result,
    };
    let result = Bytes::from(serde_json::to_vec(&view).map_err(|err| {
        tracing::error!(error = %err, "a triad's result did not serialise");
        Error::Internal
    })?);
    Ok(Assessed {
        sensor_id,
        result: result.clone(),
        record: Some(NewCalibration { result, ..record }),
    })
}
