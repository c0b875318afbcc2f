//! Token management (admin only): create, list without secrets, revoke.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use serde::Serialize;
use uuid::Uuid;

use super::extract::Body;
use super::problem::Problem;
use super::{AppState, path_id};
use crate::auth::{self, Principal, Role};
use crate::input::check::{Chars, optional};
use crate::input::{Checker, Ptr};
use crate::store::{Store, TokenRecord};
use crate::submission::{MAX_ID_CHARS, MAX_LABEL_CHARS};
use crate::timestamp::Timestamp;

/// A token as listed: never its secret.
#[derive(Debug, Serialize)]
pub struct TokenView {
    id: Uuid,
    role: Role,
    station_id: Option<String>,
    label: Option<String>,
    created_at: String,
    revoked_at: Option<String>,
}

impl From<TokenRecord> for TokenView {
    fn from(t: TokenRecord) -> Self {
        TokenView {
            id: t.id,
            role: t.role,
            station_id: t.station_id,
            label: t.label,
            created_at: t.created_at,
            revoked_at: t.revoked_at,
        }
    }
}

/// A new token, with its secret text shown this once.
#[derive(Debug, Serialize)]
pub struct CreatedToken {
    id: Uuid,
    token: String,
    role: Role,
    station_id: Option<String>,
    label: Option<String>,
    created_at: String,
}

/// What a token request asks for, checked.
pub struct TokenRequest {
    /// Role.
    pub role: Role,
    /// Bound station (station role only).
    pub station_id: Option<String>,
    /// Label.
    pub label: Option<String>,
}

/// Checks a token request body.
pub fn check_request(value: &serde_json::Value) -> Result<TokenRequest, Problem> {
    let root = Ptr::root();
    let mut c = Checker::new();
    let Some(map) = c.object(value, &root, &["role", "station_id", "label"]) else {
        return Err(c.finish().unwrap_err().into());
    };
    let role = c.required(map, &root, "role").and_then(|v| {
        let r = v.as_str().and_then(Role::parse);
        if r.is_none() {
            c.error(
                &root.key("role"),
                "must be \"reader\", \"station\" or \"admin\"",
            );
        }
        r
    });
    let station_id = optional(map, "station_id")
        .and_then(|v| c.string(v, &root.key("station_id"), MAX_ID_CHARS, Chars::Identifier));
    if station_id.is_some() && role.is_some_and(|r| r != Role::Station) {
        c.error(
            &root.key("station_id"),
            "only a station token can be bound to a station",
        );
    }
    let label = optional(map, "label")
        .and_then(|v| c.string(v, &root.key("label"), MAX_LABEL_CHARS, Chars::Line));
    c.finish()?;
    Ok(TokenRequest {
        role: role.expect("checked"),
        station_id,
        label,
    })
}

/// Generates and stores a token; returns its record and secret text.
pub async fn issue(store: &dyn Store, req: TokenRequest) -> Result<(TokenRecord, String), Problem> {
    let new = auth::generate().map_err(|e| {
        tracing::error!(error = %e, "no randomness for a token");
        Problem::internal()
    })?;
    let record = TokenRecord {
        id: new.id,
        secret_hash: new.secret_hash.to_vec(),
        role: req.role,
        station_id: req.station_id,
        label: req.label,
        created_at: Timestamp::now().to_string(),
        revoked_at: None,
    };
    store.insert_token(record.clone()).await?;
    Ok((record, new.text))
}

/// `POST /v1/tokens`.
pub async fn create(
    State(state): State<AppState>,
    principal: Principal,
    body: Body,
) -> Result<(StatusCode, Json<CreatedToken>), Problem> {
    principal.require(Role::Admin)?;
    let req = check_request(&body.json()?)?;
    let (record, token) = issue(state.store.as_ref(), req).await?;
    tracing::info!(token_id = %record.id, role = %record.role, by = %principal.id, "token created");
    Ok((
        StatusCode::CREATED,
        Json(CreatedToken {
            id: record.id,
            token,
            role: record.role,
            station_id: record.station_id,
            label: record.label,
            created_at: record.created_at,
        }),
    ))
}

/// A list of tokens.
#[derive(Debug, Serialize)]
pub struct TokenList {
    items: Vec<TokenView>,
}

/// `GET /v1/tokens`: every token, oldest first, without secrets.
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
) -> Result<Json<TokenList>, Problem> {
    principal.require(Role::Admin)?;
    let items = state
        .store
        .tokens()
        .await?
        .into_iter()
        .map(TokenView::from)
        .collect();
    Ok(Json(TokenList { items }))
}

/// `DELETE /v1/tokens/{id}`: revokes at once.
pub async fn revoke(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<StatusCode, Problem> {
    principal.require(Role::Admin)?;
    let id = path_id(&id, "token")?;
    if state.store.revoke_token(id, Timestamp::now()).await? {
        tracing::info!(token_id = %id, by = %principal.id, "token revoked");
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(Problem::not_found(format!(
            "no active token with id `{id}`"
        )))
    }
}
