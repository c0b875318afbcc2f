//! The acts on webhook endpoints (issue 47 item 3), each an admin's (the
//! transport checks the role):
//! registering or changing one (its target checked against private
//! addresses unless allowed), rotating its secret, delivering again from an
//! event, deleting it. Each is recorded in the audit trail; delivery itself
//! is [`super::delivery`]'s.

use crate::domain::audit::Actor;
use crate::domain::auth::Principal;
use crate::domain::field::{Invalid, Loc};
use crate::domain::timestamp::Timestamp;
use crate::domain::webhooks::{
    DEFAULT_OVERLAP_S, Endpoint, MAX_OVERLAP_S, RedeliverBody, RotateBody, Secret, WebhookBody,
};

use super::{Error, Lab};

fn unknown(id: &str) -> Error {
    Error::NotFound(format!("no webhook `{}`", crate::domain::text::echo(id)))
}

fn secret() -> Result<Secret, Error> {
    Secret::generate().map_err(|e| {
        tracing::error!(error = %e, "no randomness for a webhook secret");
        Error::Internal
    })
}

/// Registers (with its secret, shown this once) or changes the endpoint
/// `id`; a target whose addresses are private or loopback is refused at
/// `/url` unless `allow_private`.
pub async fn put(
    lab: &Lab,
    principal: &Principal,
    id: String,
    body: WebhookBody,
    allow_private: bool,
) -> Result<(Endpoint, Option<Secret>), Error> {
    let (def, url) = body.check(id).map_err(Error::Invalid)?;
    if !allow_private && let Err(why) = super::delivery::check_host(&url).await {
        return Err(Error::Invalid(Invalid::one(Loc::Root.key("url"), why)));
    }
    let head = lab.store.audit_head().await.map_err(Error::Store)?;
    let new = secret()?;
    let (stored, created) = lab
        .store
        .put_webhook(
            def,
            new.clone(),
            head,
            Timestamp::now(),
            Actor::from(principal),
        )
        .await
        .map_err(Error::Store)?;
    Ok((stored, created.then_some(new)))
}

/// Replaces the endpoint's secret; the old one signs beside the new for
/// the overlap asked (default a day, at most a week).
pub async fn rotate(
    lab: &Lab,
    principal: &Principal,
    id: String,
    body: RotateBody,
) -> Result<(Endpoint, Secret), Error> {
    let overlap = body.overlap_s.unwrap_or(DEFAULT_OVERLAP_S);
    if !(0..=MAX_OVERLAP_S).contains(&overlap) {
        return Err(Error::invalid(
            Loc::Root.key("overlap_s"),
            format!("is {overlap}: from 0 to {MAX_OVERLAP_S} seconds"),
        ));
    }
    let new = secret()?;
    let now = Timestamp::now();
    let stored = lab
        .store
        .rotate_webhook(
            id.clone(),
            new.clone(),
            now.plus_seconds(overlap),
            now,
            Actor::from(principal),
        )
        .await
        .map_err(Error::Store)?
        .ok_or_else(|| unknown(&id))?;
    Ok((stored, new))
}

/// Delivers again every event of the endpoint after `after` (an event id
/// no later than the trail's head), in order, with their own ids.
pub async fn redeliver(
    lab: &Lab,
    principal: &Principal,
    id: String,
    body: RedeliverBody,
) -> Result<Endpoint, Error> {
    let head = lab.store.audit_head().await.map_err(Error::Store)?;
    if !(0..=head).contains(&body.after) {
        return Err(Error::invalid(
            Loc::Root.key("after"),
            format!(
                "is {}: an event id from 0 to the latest, {head}",
                body.after
            ),
        ));
    }
    lab.store
        .redeliver_webhook(
            id.clone(),
            body.after,
            Timestamp::now(),
            Actor::from(principal),
        )
        .await
        .map_err(Error::Store)?
        .ok_or_else(|| unknown(&id))
}

/// Deletes the endpoint and its delivery log.
pub async fn delete(lab: &Lab, principal: &Principal, id: String) -> Result<(), Error> {
    let gone = lab
        .store
        .delete_webhook(id.clone(), Timestamp::now(), Actor::from(principal))
        .await
        .map_err(Error::Store)?;
    if gone { Ok(()) } else { Err(unknown(&id)) }
}

/// One endpoint.
pub async fn get(lab: &Lab, id: String) -> Result<Endpoint, Error> {
    lab.store
        .webhook(id.clone())
        .await
        .map_err(Error::Store)?
        .ok_or_else(|| unknown(&id))
}
