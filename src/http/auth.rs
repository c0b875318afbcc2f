//! The caller: the [`Principal`] behind a request's bearer token, with
//! failed authentications throttled per client address ([`super::throttle`]).

use std::time::Instant;

use axum::extract::FromRequestParts;
use axum::http::request::Parts;
use axum::http::{HeaderMap, StatusCode, header};
use subtle::ConstantTimeEq;

use super::AppState;
use super::problem::Problem;
use super::throttle::AddrKey;
use crate::domain::auth::{self, ENV_ADMIN, Principal, Role};

impl FromRequestParts<AppState> for Principal {
    type Rejection = Problem;

    /// The principal admission already authenticated (a request with a
    /// body), else the bearer token's.
    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, Problem> {
        if let Some(p) = parts.extensions.get::<Principal>() {
            return Ok(p.clone());
        }
        let client = parts.extensions.get::<ClientAddr>().copied();
        bearer(state, &parts.headers, client).await
    }
}

/// The client's address, put in every request's extensions by the server
/// (absent when the router is called without a connection, as in tests).
#[derive(Clone, Copy, Debug)]
pub struct ClientAddr(pub std::net::IpAddr);

/// The principal behind a request's `Authorization: Bearer` header: 401
/// without one (or with another scheme), 400 for two, and as
/// [`authenticate`] for the token.
pub async fn bearer(
    state: &AppState,
    headers: &HeaderMap,
    client: Option<ClientAddr>,
) -> Result<Principal, Problem> {
    let mut values = headers.get_all(header::AUTHORIZATION).iter();
    let value = values
        .next()
        .ok_or_else(|| Problem::unauthorized("send `Authorization: Bearer <token>`"))?;
    if values.next().is_some() {
        // Which one would a proxy, a log or another server believe?
        return Err(Problem::bad_parameter(
            "Authorization",
            "is sent more than once; send exactly one",
        ));
    }
    let text = value
        .to_str()
        .ok()
        .and_then(|v| v.split_once(' '))
        .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
        .map(|(_, token)| token.trim())
        .ok_or_else(|| {
            Problem::unauthorized("the Authorization header must read `Bearer <token>`")
        })?;
    authenticate(state, text, client).await.map(|(p, _)| p)
}

/// The principal behind a token's text, and the hash of the credential it
/// presented (the secret's, or the whole configured admin token's): 401 for
/// an unknown, malformed or revoked token; 429 while `client` is throttled
/// for failing too often ([`super::throttle`]) and the token cannot be
/// judged without the database.
pub async fn authenticate(
    state: &AppState,
    text: &str,
    client: Option<ClientAddr>,
) -> Result<(Principal, [u8; 32]), Problem> {
    if let Some(admin) = &state.admin_token_hash
        && bool::from(auth::hash(text).ct_eq(admin))
    {
        let principal = Principal {
            id: ENV_ADMIN.to_owned(),
            role: Role::Admin,
            station_id: None,
            holder: None,
        };
        return Ok((principal, *admin));
    }
    let now = Instant::now();
    let addr = client.map(|c| AddrKey::from(c.0));
    let parsed = auth::parse(text);
    if let Some(addr) = addr
        && let Some(wait) = state.throttle.blocked(addr, now)
        && !parsed.is_some_and(|(id, _)| state.throttle.trusted(id))
    {
        return Err(Problem::too_many(
            "too many failed authentications from this address; retry later",
            wait,
        ));
    }
    let outcome = verify(state, parsed).await;
    match &outcome {
        Ok(_) => {
            if let Some((id, _)) = parsed {
                state.throttle.succeeded(id);
            }
        }
        Err(problem) if problem.status == StatusCode::UNAUTHORIZED => {
            if let Some(addr) = addr {
                state.throttle.failed(addr, now);
            }
        }
        Err(_) => {}
    }
    outcome
}

/// Checks an issued token's secret and revocation.
async fn verify(
    state: &AppState,
    parsed: Option<(uuid::Uuid, &str)>,
) -> Result<(Principal, [u8; 32]), Problem> {
    let invalid = || Problem::unauthorized("the token is not valid");
    let (id, secret) = parsed.ok_or_else(invalid)?;
    let record = state.store.token(id).await?.ok_or_else(invalid)?;
    if !auth::verify(secret, &record.secret_hash) {
        return Err(invalid());
    }
    if record.revoked_at.is_some() {
        return Err(Problem::unauthorized("the token has been revoked"));
    }
    Ok((
        Principal {
            id: record.id.simple().to_string(),
            role: record.role,
            station_id: record.station_id,
            holder: record.holder,
        },
        auth::hash(secret),
    ))
}

/// The principal of a session opened as `principal_id` with a credential
/// hashing to `credential`, if that credential is still good: the token is
/// not revoked (or the configured admin token unchanged).
pub async fn still_valid(
    state: &AppState,
    principal_id: &str,
    credential: &[u8; 32],
) -> Result<Option<Principal>, Problem> {
    if principal_id == ENV_ADMIN {
        let same = state
            .admin_token_hash
            .is_some_and(|admin| bool::from(admin.ct_eq(credential)));
        return Ok(same.then(|| Principal {
            id: ENV_ADMIN.to_owned(),
            role: Role::Admin,
            station_id: None,
            holder: None,
        }));
    }
    let Ok(id) = uuid::Uuid::try_parse(principal_id) else {
        return Ok(None);
    };
    let Some(record) = state.store.token(id).await? else {
        return Ok(None);
    };
    let good = record.revoked_at.is_none() && bool::from(record.secret_hash.ct_eq(credential));
    Ok(good.then(|| Principal {
        id: record.id.simple().to_string(),
        role: record.role,
        station_id: record.station_id,
        holder: record.holder,
    }))
}

/// Refuses (403) a principal whose role is below `role`.
pub fn require(principal: &Principal, role: Role) -> Result<(), Problem> {
    if principal.role >= role {
        Ok(())
    } else {
        Err(Problem::forbidden(format!(
            "this operation needs a {role} token; this token's role is {}",
            principal.role
        )))
    }
}

/// The station recorded on (or named in) a submission: a bound token's
/// station, which the body may repeat but not contradict; otherwise the
/// body's `station_id` (an unbound station token may name any station).
pub fn station(principal: &Principal, claimed: Option<&str>) -> Result<Option<String>, Problem> {
    match (&principal.station_id, claimed) {
        (Some(bound), Some(claimed)) if bound != claimed => Err(Problem::forbidden(format!(
            "this token is bound to station `{bound}` and cannot act as `{}`",
            crate::domain::text::echo(claimed)
        ))),
        (Some(bound), _) => Ok(Some(bound.clone())),
        (None, claimed) => Ok(claimed.map(str::to_owned)),
    }
}
