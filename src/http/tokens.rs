//! Token management (admin only): create, list without secrets, revoke.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use serde::Serialize;
use utoipa::ToSchema;

use super::auth::require;
use super::body::Body;
use super::problem::Problem;
use super::{AppState, path_id};
use crate::app::tokens;
use crate::domain::audit::Actor;
use crate::domain::auth::{Principal, Role};
use crate::domain::tokens::{CreatedToken, TokenRequest, TokenView};

/// `POST /v1/tokens`.
#[utoipa::path(
    post,
    path = "/v1/tokens",
    tag = "tokens",
    operation_id = "createToken",
    summary = "Create a token (admin). The secret is shown only in this answer.",
    request_body(content((TokenRequest = "application/json"))),
    responses(
        (status = 201, description = "Created.", body = CreatedToken,
            links(("RevokeToken" = (operation_id = "revokeToken", parameters(("id" = "$response.body#/id")))))),
        (status = 403, response = super::openapi::Forbidden),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn create(
    State(state): State<AppState>,
    principal: Principal,
    body: Body,
) -> Result<(StatusCode, Json<CreatedToken>), Problem> {
    require(&principal, Role::Admin)?;
    let request = body.json::<TokenRequest>()?.check()?;
    let created = tokens::create(&state.lab, Actor::from(&principal), request).await?;
    Ok((StatusCode::CREATED, Json(created)))
}

/// A list of tokens.
#[derive(Debug, Serialize, ToSchema)]
pub struct TokenList {
    /// Every token, oldest first.
    items: Vec<TokenView>,
}

/// `GET /v1/tokens`: every token, oldest first, without secrets.
#[utoipa::path(
    get,
    path = "/v1/tokens",
    tag = "tokens",
    operation_id = "listTokens",
    summary = "Every token, without secrets (admin).",
    responses(
        (status = 200, description = "The tokens.", body = TokenList),
        (status = 403, response = super::openapi::Forbidden),
        super::openapi::Always,
    )
)]
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
) -> Result<Json<TokenList>, Problem> {
    require(&principal, Role::Admin)?;
    let items = state
        .store
        .tokens()
        .await?
        .iter()
        .map(TokenView::from)
        .collect();
    Ok(Json(TokenList { items }))
}

/// `DELETE /v1/tokens/{id}`: revokes at once. A whole token pasted as the id
/// is not echoed (its secret is redacted from the answer and the log).
#[utoipa::path(
    delete,
    path = "/v1/tokens/{id}",
    tag = "tokens",
    operation_id = "revokeToken",
    summary = "Revoke a token at once (admin).",
    params(("id" = uuid::Uuid, Path, description = "The token's id.")),
    responses(
        (status = 204, description = "Revoked."),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn revoke(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<StatusCode, Problem> {
    require(&principal, Role::Admin)?;
    let id = path_id(&id, "token")?;
    tokens::revoke(&state.lab, &principal, id).await?;
    Ok(StatusCode::NO_CONTENT)
}
