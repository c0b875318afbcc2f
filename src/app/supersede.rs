//! Correcting a stored calibration: superseding it by a corrected
//! submission, and reprocessing its stored submission with the current
//! method — confirmed when every number is the same, superseded otherwise.
//! The replacement is computed as the old calibration's kind is computed
//! and stored with the supersession in one transaction, or neither.

use accelcal_core::TermMap;
use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::review::{outcome, unknown};
use super::{Error, Kind, Lab, Submitted, Upload};
use crate::domain::auth::Principal;
use crate::domain::review::{Act, Action, Signature, Supersedes, supersession};
use crate::domain::submission::Method;
use crate::domain::timestamp::Timestamp;
use crate::store::{CalibrationSummary, NewCalibration};

/// Supersedes calibration `old` by `upload`, a corrected submission, for
/// `reason` (already checked): the calibration must exist before anything
/// is computed; its state, and whether `principal` may supersede it, are
/// checked where the act is recorded.
pub async fn supersede(
    lab: &Lab,
    principal: Principal,
    old: Uuid,
    reason: String,
    upload: Upload,
) -> Result<Submitted, Error> {
    let Some(summary) = lab.store.calibration_summary(old).await? else {
        return Err(unknown(old));
    };
    let received_at = Timestamp::now();
    let new = Uuid::now_v7();
    let supersedes = Supersedes {
        calibration_id: old,
        reason: reason.clone(),
    };
    // Computed as the calibration it supersedes is, whatever the body.
    let assessed = Kind::of(&summary)
        .assess(lab, &principal, upload, received_at, new, Some(supersedes))
        .await?;
    let Some(record) = assessed.record else {
        return Err(Error::Internal);
    };
    let act = supersession(reason, principal, received_at, new);
    outcome(lab.store.supersede(old, record, act).await?, old)?;
    tracing::info!(calibration = %old, by = %new, "calibration superseded");
    metrics::counter!("accelcal_reviews_total", "action" => "supersede").increment(1);
    Ok(Submitted {
        id: new,
        result: assessed.result,
        replayed: false,
    })
}

/// What reprocessing came to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// Every number the same: the calibration is confirmed as it is.
    Confirmed,
    /// Some number differs: a new calibration supersedes it.
    Superseded,
}

/// The answer of `POST /v1/calibrations/{id}/reprocess`.
#[derive(Debug, Serialize, ToSchema)]
pub struct Reprocessed {
    /// The calibration reprocessed.
    pub calibration_id: Uuid,
    /// `confirmed` or `superseded`.
    pub outcome: Outcome,
    /// The calibration that supersedes it, when a number differs.
    pub replacement_id: Option<Uuid>,
    /// What differs (`ki coefficient`, `k0 expanded uncertainty`, …); empty
    /// when confirmed.
    pub changed: Vec<String>,
    /// The signature recorded on it.
    pub signature: Signature,
}

/// What differs between a stored calibration and its submission computed
/// again: the model, unit, runs, and every fused coefficient, standard
/// error and expanded uncertainty — a triad's method and every element of
/// `b`, `S`, `T` (and `S2`) with their standard errors and expanded
/// uncertainties — compared bit for bit.
fn differences(old: &CalibrationSummary, new: &NewCalibration) -> Vec<String> {
    let mut changed = Vec::new();
    if old.model != new.model {
        changed.push("model".to_owned());
    }
    if old.unit != new.unit {
        changed.push("unit".to_owned());
    }
    if old.runs != new.runs {
        changed.push("runs".to_owned());
    }
    let none = TermMap(Vec::new());
    for (what, a, b) in [
        ("coefficient", &old.coefficients, &new.coefficients),
        ("standard error", &old.std_errors, &new.std_errors),
        (
            "expanded uncertainty",
            old.expanded.as_ref().unwrap_or(&none),
            new.expanded.as_ref().unwrap_or(&none),
        ),
    ] {
        for (term, x) in b.iter() {
            if a.get(term).is_none_or(|y| y.to_bits() != x.to_bits()) {
                changed.push(format!("{} {what}", term.name()));
            }
        }
        for (term, _) in a.iter().filter(|(t, _)| b.get(*t).is_none()) {
            changed.push(format!("{} {what}", term.name()));
        }
    }
    match (&old.triad, &new.triad) {
        (Some(a), Some(b)) => {
            if a.method != b.method {
                changed.push("method".to_owned());
            }
            let (was, now) = (a.numbers(), b.numbers());
            for (name, x) in &now {
                if was
                    .iter()
                    .find(|(n, _)| n == name)
                    .is_none_or(|(_, y)| y.to_bits() != x.to_bits())
                {
                    changed.push(name.clone());
                }
            }
            for (name, _) in was.iter().filter(|(n, _)| !now.iter().any(|(m, _)| m == n)) {
                changed.push(name.clone());
            }
        }
        (None, None) => {}
        _ => changed.push("kind".to_owned()),
    }
    changed
}

/// Reprocesses calibration `id` for `principal`: its stored submission
/// evaluated again as it was received (same body, same reception time)
/// with this accelcal's method. When every number is the same
/// ([`differences`]), a `confirm` signature records it and the state is
/// kept; otherwise a new calibration supersedes it, with the reason
/// "reprocessed with accelcal … (core …)" and what changed. The sensor's
/// type and the standards are today's.
pub async fn reprocess(lab: &Lab, principal: Principal, id: Uuid) -> Result<Reprocessed, Error> {
    let old = lab
        .store
        .calibration_summary(id)
        .await?
        .ok_or_else(|| unknown(id))?;
    let stored = lab.store.submission(id).await?.ok_or_else(|| unknown(id))?;
    let upload = Upload::stored(stored.content_type, stored.body);
    let method = Method::CURRENT;
    let reason = format!(
        "reprocessed with accelcal {} (core {})",
        method.accelcal, method.core
    );
    let new = Uuid::now_v7();
    let supersedes = Supersedes {
        calibration_id: id,
        reason: reason.clone(),
    };
    // As it was received: the same body at the same reception time.
    let assessed = Kind::of(&old)
        .assess(
            lab,
            &principal,
            upload,
            old.received_at,
            new,
            Some(supersedes),
        )
        .await?;
    let Some(record) = assessed.record else {
        return Err(Error::Internal);
    };
    let changed = differences(&old, &record);
    let now = Timestamp::now();
    let (signed, replacement_id) = if changed.is_empty() {
        let act = Act {
            action: Action::Confirm,
            signer: principal,
            at: now,
            comment: Some(reason),
            superseded_by: None,
        };
        (lab.store.sign(id, act).await?, None)
    } else {
        let why = format!("{reason}: {} changed", changed.join(", "));
        let act = supersession(why, principal, now, new);
        (lab.store.supersede(id, record, act).await?, Some(new))
    };
    let reviewed = outcome(signed, id)?;
    let result = if replacement_id.is_some() {
        Outcome::Superseded
    } else {
        Outcome::Confirmed
    };
    let action = if replacement_id.is_some() {
        "supersede"
    } else {
        "confirm"
    };
    metrics::counter!("accelcal_reviews_total", "action" => action).increment(1);
    tracing::info!(calibration = %id, outcome = ?result, "calibration reprocessed");
    Ok(Reprocessed {
        calibration_id: id,
        outcome: result,
        replacement_id,
        changed,
        signature: reviewed.signature,
    })
}
