//! Issuing and revoking access tokens: a token's secret is generated here
//! and shown once, only its hash stored; each act recorded with its audit
//! entry in one transaction.

use uuid::Uuid;

use super::{Error, Lab};
use crate::domain::audit::Actor;
use crate::domain::auth::Principal;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::{CreatedToken, TokenRequest, issue};

/// Issues the token `request` (checked) asks for, recorded as `by`'s act
/// (an admin's token, or the command line's operator): the answer that
/// shows its secret, once.
pub async fn create(lab: &Lab, by: Actor, request: TokenRequest) -> Result<CreatedToken, Error> {
    let (record, created) = issue(request, Timestamp::now()).map_err(|e| {
        tracing::error!(error = %e, "no randomness for a token");
        Error::Internal
    })?;
    let who = by.token_id.clone();
    lab.store.insert_token(record, by).await?;
    tracing::info!(token_id = %created.id, role = %created.role, by = %who, "token created");
    Ok(created)
}

/// Revokes token `id`, by `principal` (not found unless it is active).
pub async fn revoke(lab: &Lab, principal: &Principal, id: Uuid) -> Result<(), Error> {
    if lab
        .store
        .revoke_token(id, Timestamp::now(), Actor::from(principal))
        .await?
    {
        tracing::info!(token_id = %id, by = %principal.id, "token revoked");
        Ok(())
    } else {
        Err(Error::NotFound(format!("no active token with id `{id}`")))
    }
}
