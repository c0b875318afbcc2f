//! The single-axis kind: a tumble-test submission checked, identified and
//! fused (on the compute pool when it is large), then assessed with what
//! the records know of its sensor — the sensor type in force, the
//! registered standards, the previous calibration — and its result
//! document rendered once. What `POST /v1/identify` answers and what a
//! submission, a correction and a reprocessing store.

use bytes::Bytes;
use uuid::Uuid;

use super::standards::{Resolved, resolve};
use super::subject::{in_force, station};
use super::{Assessed, Error, Lab, Upload};
use crate::domain::auth::Principal;
use crate::domain::metrology::{Previous, assess_calibration};
use crate::domain::review::Supersedes;
use crate::domain::submission::{Evaluated, ResultView, StandardsIn, Submission, evaluate};
use crate::domain::timestamp::Timestamp;
use crate::store::NewCalibration;

/// Resolves the standards `e` names against the registry, for a test
/// performed at `performed_at` ([`resolve`]); the stand's indexing error
/// and the gravity value's relative uncertainty become the submission's
/// stand. Temperature models resolve theirs so too.
pub(super) async fn resolve_standards(
    lab: &Lab,
    sub: &mut Submission,
    performed_at: Timestamp,
) -> Result<(), Error> {
    let Some(named) = &sub.standards else {
        return Ok(());
    };
    let r = resolve(lab, &roles(named), performed_at).await?;
    sub.stand = Some(r.stand);
    sub.standards_used = r.used;
    sub.held_by = r.held_by;
    Ok(())
}

/// The standards `named` by role, as [`resolve`] takes them.
pub(super) fn roles(named: &StandardsIn) -> [(&'static str, Option<String>); 3] {
    [
        ("stand", Some(named.stand.clone())),
        ("thermometer", named.thermometer.clone()),
        ("gravity", named.gravity.clone()),
    ]
}

/// Evaluates `upload` for `principal`; with `id`, also builds the record
/// to store under that id — which, with `supersedes`, records the
/// calibration it corrects.
pub async fn assess(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    received_at: Timestamp,
    id: Option<Uuid>,
    supersedes: Option<Supersedes>,
) -> Result<Assessed, Error> {
    let (bytes, content_type) = (upload.bytes.clone(), upload.content_type.clone());
    let size = bytes.len();
    let who = principal.clone();
    let (mut evaluated, station_id) = lab
        .compute_for(
            size,
            move || -> Result<(Evaluated, Option<String>), Error> {
                let e = evaluate(upload.media, &upload.bytes, received_at)?;
                let station_id = station(&who, e.submission.station_id.as_deref())?;
                Ok((e, station_id))
            },
        )
        .await??;
    let subject = in_force(
        lab,
        principal,
        &evaluated.submission.sensor_id,
        evaluated.submission.sensor_type.as_ref(),
        false,
        received_at,
    )
    .await?;
    let performed_at = evaluated.submission.performed_at.unwrap_or(received_at);
    resolve_standards(lab, &mut evaluated.submission, performed_at).await?;
    let previous = subject
        .previous(lab, performed_at)
        .await?
        .map(|c| Previous {
            id: c.id,
            unit: c.unit,
            coefficients: c.coefficients,
        });
    let sensor_type = subject.sensor_type;
    let submitted_by = principal.id.clone();
    lab.compute_for(size, move || -> Result<Assessed, Error> {
        let e = &evaluated;
        let type_id = sensor_type.as_ref().map(|t| t.type_id.as_str());
        let metrology =
            assess_calibration(e, performed_at, sensor_type.as_ref(), previous.as_ref())?;
        let mut view = ResultView::new(
            e,
            id,
            station_id.as_deref(),
            received_at,
            type_id,
            &metrology,
        );
        view.supersedes = supersedes;
        let result = Bytes::from(serde_json::to_vec(&view).map_err(|err| {
            tracing::error!(error = %err, "a result did not serialise");
            Error::Internal
        })?);
        let fused = &e.calibration.fused;
        let record = id.map(|id| NewCalibration {
            id,
            sensor_id: e.submission.sensor_id.clone(),
            performed_at,
            received_at,
            unit: e.submission.unit.clone(),
            model: e.submission.test.model().clone(),
            runs: e.calibration.runs.len(),
            coefficients: fused.coefficients.clone(),
            std_errors: fused.std_errors.clone(),
            result: result.clone(),
            submission: bytes,
            content_type,
            submitted_by,
            station_id: station_id.clone(),
            sensor_type: type_id.map(str::to_owned),
            assigns_type: e.submission.sensor_type.is_some(),
            verdict: metrology.decision.as_ref().map(|d| d.verdict),
            due_at: metrology.due_at,
            expanded: Some(metrology.uncertainty.expanded()),
            triad: None,
            thermal: None,
            thermal_triad: None,
            standards: Resolved::uses(&e.submission.standards_used),
            fitted_from: Vec::new(),
        });
        Ok(Assessed {
            sensor_id: e.submission.sensor_id.clone(),
            result,
            record,
        })
    })
    .await?
}
