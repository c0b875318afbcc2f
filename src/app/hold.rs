//! Holding the calibrations a faulty standard may have spoilt (issue 29
//! item 3): the standard's nonconformity recorded, and every calibration
//! made with it in the affected window that counts placed under review (a
//! `hold` signature) in the same transaction — its coefficients unusable
//! until a reviewer approves it again (the disposition,
//! [`super::review`]) or withdraws it.

use super::{Error, Lab};
use crate::domain::audit::Actor;
use crate::domain::auth::Principal;
use crate::domain::limits::MAX_ID_CHARS;
use crate::domain::nonconformity::{NonconformityBody, Outcome, Traced};
use crate::domain::review::{Act, Action};
use crate::domain::standards::Standard;
use crate::domain::text::{Chars, check_str, echo};
use crate::domain::timestamp::Timestamp;

/// No standard `standard_id`.
pub fn unknown_standard(standard_id: &str) -> Error {
    Error::NotFound(format!("no standard `{}`", echo(standard_id)))
}

/// The standard `standard_id` (not found when its id could not be valid).
pub async fn known(lab: &Lab, standard_id: &str) -> Result<Standard, Error> {
    if check_str(standard_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(unknown_standard(standard_id));
    }
    lab.store
        .standard(standard_id.to_owned())
        .await?
        .ok_or_else(|| unknown_standard(standard_id))
}

/// Records `principal`'s finding that `standard` ([`known`]) is
/// nonconforming, and holds the calibrations of its window: what became of
/// each.
pub async fn nonconformity(
    lab: &Lab,
    principal: &Principal,
    standard: &Standard,
    body: NonconformityBody,
) -> Result<Traced, Error> {
    let standard_id = &standard.standard_id;
    let now = Timestamp::now();
    let nc = body.check(uuid::Uuid::now_v7(), standard, now, Actor::from(principal))?;
    let hold = Act {
        action: Action::Hold,
        signer: principal.clone(),
        at: now,
        comment: Some(format!(
            "standard {standard_id} found nonconforming {}: {}",
            nc.found_at, nc.reason
        )),
        superseded_by: None,
    };
    let calibrations = lab.store.hold(nc.clone(), hold).await?;
    let held = calibrations
        .iter()
        .filter(|c| c.outcome == Outcome::UnderReview)
        .count();
    metrics::counter!("accelcal_reviews_total", "action" => "hold").increment(held as u64);
    tracing::warn!(
        standard = %standard_id, nonconformity = %nc.id, held,
        by = %principal.id, "standard found nonconforming"
    );
    Ok(Traced {
        nonconformity: nc,
        calibrations,
    })
}
