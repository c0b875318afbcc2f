//! Reviewing a stored calibration (issue 28): approving or rejecting,
//! withdrawing, confirming — each act checked by the domain
//! ([`crate::domain::review::Act::check`]) inside the store's transaction
//! that records it: a refusal for the signer's role or their own work is
//! forbidden, one for the calibration's state (approving a withdrawn one,
//! withdrawing twice) a state conflict naming the state. An approval issues
//! the certificate in its transaction.

use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::{Error, Lab};
use crate::domain::review::{Act, Action, Refusal, Signature, State};
use crate::domain::timestamp::Timestamp;
use crate::store::{Render, Signed};

/// What an act came to: the calibration's new state and the signature.
#[derive(Debug, Serialize, ToSchema)]
pub struct Reviewed {
    /// The calibration.
    pub calibration_id: Uuid,
    /// Its state now.
    pub state: State,
    /// The signature just recorded.
    pub signature: Signature,
}

/// The certificate an approval issues, rendered from what was read before
/// the act, when it could be: given the approval's instant, the renderer
/// of its documents (with the signatures and state the approval leaves).
pub type Issuing = Box<dyn FnOnce(Timestamp) -> Render + Send>;

/// No calibration `id`.
pub fn unknown(id: Uuid) -> Error {
    Error::NotFound(format!("no calibration with id `{id}`"))
}

/// Records `act` on calibration `id`. An approval issues its certificate
/// in its transaction with `issuing`; without one (no certificate could be
/// rendered: an unknown calibration, or a stored result that does not read
/// back) the approval is judged as any other act, and the certificate is
/// issued at its first request.
pub async fn record(
    lab: &Lab,
    id: Uuid,
    act: Act,
    issuing: Option<Issuing>,
) -> Result<Reviewed, Error> {
    let action = act.action;
    let signed = match (action, issuing) {
        (Action::Approve, Some(issuing)) => {
            let render = issuing(act.at);
            lab.store.approve_issuing(id, act, render).await?
        }
        _ => lab.store.sign(id, act).await?,
    };
    let reviewed = outcome(signed, id)?;
    metrics::counter!("accelcal_reviews_total", "action" => action.as_str()).increment(1);
    tracing::info!(
        calibration = %id, action = action.as_str(),
        by = %reviewed.signature.token_id, "calibration signed"
    );
    Ok(reviewed)
}

/// What the store made of an act on calibration `id`.
pub fn outcome(signed: Signed, id: Uuid) -> Result<Reviewed, Error> {
    match signed {
        Signed::Done(signature, _) => Ok(Reviewed {
            calibration_id: id,
            state: signature.state,
            signature,
        }),
        Signed::NotFound => Err(unknown(id)),
        Signed::Refused(why) if why.is_permission() => Err(Error::Forbidden {
            why: why.to_string(),
            fields: None,
        }),
        Signed::Refused(why @ Refusal::Disposition) => {
            Err(Error::invalid("/comment", why.to_string()))
        }
        Signed::Refused(why) => Err(Error::State(why.to_string())),
    }
}
