//! Webhook endpoints (issue 47 item 3), all an admin's: registered by
//! `PUT` (the secret shown once), listed, read, rotated, redelivered from
//! an event, deleted, and each one's delivery log. Delivery is
//! [`crate::app::delivery`]'s.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::lookup::path_identifier;
use super::problem::Problem;
use super::query::Params;
use crate::app::webhooks;
use crate::domain::auth::{Principal, Role};
use crate::domain::limits::MAX_PAGE;
use crate::domain::webhooks::{Delivery, RedeliverBody, RotateBody, Webhook, WebhookBody};

/// An endpoint just registered or rotated: its secret, shown only here.
#[derive(Debug, Serialize, ToSchema)]
pub struct WithSecret {
    /// The endpoint.
    pub webhook: Webhook,
    /// Its signing secret (`whsec_…`, Standard Webhooks): shown once, kept
    /// by the receiver to verify `webhook-signature`.
    pub secret: String,
}

/// `PUT /v1/webhooks/{webhook_id}`.
#[utoipa::path(
    put,
    path = "/v1/webhooks/{webhook_id}",
    tag = "webhooks",
    operation_id = "putWebhook",
    summary = "Register (201, with its secret, shown once) or change (200) a webhook endpoint (admin).",
    params(("webhook_id" = crate::domain::schema::Identifier, Path, description = "The endpoint's id.")),
    request_body(content((WebhookBody = "application/json",
        example = json!({"url": "https://control.example.com/accelcal", "event_types": ["calibration.withdrawn", "calibration.held"], "sensors": ["ACC-0042"]})))),
    responses(
        (status = 200, description = "Changed; the secret stays as it was.", body = Webhook),
        (status = 201, description = "Registered.", body = WithSecret),
        (status = 400, response = super::openapi::BadRequest),
        (status = 403, response = super::openapi::Forbidden),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn put(
    State(state): State<AppState>,
    principal: Principal,
    Path(webhook_id): Path<String>,
    body: Body,
) -> Result<axum::response::Response, Problem> {
    use axum::response::IntoResponse;
    require(&principal, Role::Admin)?;
    path_identifier(&webhook_id, "webhook")?;
    let body = body.json::<WebhookBody>()?;
    let allow = state.web.webhooks.allow_private;
    let (stored, secret) = webhooks::put(&state.lab, &principal, webhook_id, body, allow).await?;
    state.deliveries.notify_one();
    let webhook = Webhook::from(&stored);
    Ok(match secret {
        Some(s) => (
            StatusCode::CREATED,
            Json(WithSecret {
                webhook,
                secret: s.expose().to_owned(),
            }),
        )
            .into_response(),
        None => Json(webhook).into_response(),
    })
}

/// The endpoints.
#[derive(Debug, Serialize, ToSchema)]
pub struct WebhookList {
    /// Every endpoint, in id order.
    pub items: Vec<Webhook>,
}

/// `GET /v1/webhooks`.
#[utoipa::path(
    get,
    path = "/v1/webhooks",
    tag = "webhooks",
    operation_id = "listWebhooks",
    summary = "Every webhook endpoint, without secrets (admin).",
    responses(
        (status = 200, description = "The endpoints.", body = WebhookList),
        (status = 403, response = super::openapi::Forbidden),
        super::openapi::Always,
    )
)]
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
) -> Result<Json<WebhookList>, Problem> {
    require(&principal, Role::Admin)?;
    let all = crate::store::Webhooks::webhooks(state.store.as_ref())
        .await
        .map_err(crate::app::Error::Store)?;
    Ok(Json(WebhookList {
        items: all.iter().map(Webhook::from).collect(),
    }))
}

/// `GET /v1/webhooks/{webhook_id}`.
#[utoipa::path(
    get,
    path = "/v1/webhooks/{webhook_id}",
    tag = "webhooks",
    operation_id = "getWebhook",
    summary = "One webhook endpoint and where its deliveries stand (admin).",
    params(("webhook_id" = crate::domain::schema::Identifier, Path, description = "The endpoint's id.")),
    responses(
        (status = 200, description = "The endpoint.", body = Webhook),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(webhook_id): Path<String>,
) -> Result<Json<Webhook>, Problem> {
    require(&principal, Role::Admin)?;
    path_identifier(&webhook_id, "webhook")?;
    let e = webhooks::get(&state.lab, webhook_id).await?;
    Ok(Json(Webhook::from(&e)))
}

/// `DELETE /v1/webhooks/{webhook_id}`.
#[utoipa::path(
    delete,
    path = "/v1/webhooks/{webhook_id}",
    tag = "webhooks",
    operation_id = "deleteWebhook",
    summary = "Delete a webhook endpoint and its delivery log (admin).",
    params(("webhook_id" = crate::domain::schema::Identifier, Path, description = "The endpoint's id.")),
    responses(
        (status = 204, description = "Deleted."),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn delete(
    State(state): State<AppState>,
    principal: Principal,
    Path(webhook_id): Path<String>,
) -> Result<StatusCode, Problem> {
    require(&principal, Role::Admin)?;
    path_identifier(&webhook_id, "webhook")?;
    webhooks::delete(&state.lab, &principal, webhook_id).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// `POST /v1/webhooks/{webhook_id}/secret`.
#[utoipa::path(
    post,
    path = "/v1/webhooks/{webhook_id}/secret",
    tag = "webhooks",
    operation_id = "rotateWebhookSecret",
    summary = "Replace an endpoint's secret (admin): the new one shown once, the old one signing beside it for the overlap.",
    params(("webhook_id" = crate::domain::schema::Identifier, Path, description = "The endpoint's id.")),
    request_body(content((RotateBody = "application/json", example = json!({"overlap_s": 3600})))),
    responses(
        (status = 200, description = "Rotated.", body = WithSecret),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn rotate(
    State(state): State<AppState>,
    principal: Principal,
    Path(webhook_id): Path<String>,
    body: Body,
) -> Result<Json<WithSecret>, Problem> {
    require(&principal, Role::Admin)?;
    path_identifier(&webhook_id, "webhook")?;
    let body = body.json::<RotateBody>()?;
    let (stored, secret) = webhooks::rotate(&state.lab, &principal, webhook_id, body).await?;
    Ok(Json(WithSecret {
        webhook: Webhook::from(&stored),
        secret: secret.expose().to_owned(),
    }))
}

/// `POST /v1/webhooks/{webhook_id}/redeliver`.
#[utoipa::path(
    post,
    path = "/v1/webhooks/{webhook_id}/redeliver",
    tag = "webhooks",
    operation_id = "redeliverWebhook",
    summary = "Deliver again every event of the endpoint after an event id, in order, with the same webhook-ids (admin).",
    params(("webhook_id" = crate::domain::schema::Identifier, Path, description = "The endpoint's id.")),
    request_body(content((RedeliverBody = "application/json", example = json!({"after": 1200})))),
    responses(
        (status = 202, description = "Redelivery started.", body = Webhook),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn redeliver(
    State(state): State<AppState>,
    principal: Principal,
    Path(webhook_id): Path<String>,
    body: Body,
) -> Result<(StatusCode, Json<Webhook>), Problem> {
    require(&principal, Role::Admin)?;
    path_identifier(&webhook_id, "webhook")?;
    let body = body.json::<RedeliverBody>()?;
    let stored = webhooks::redeliver(&state.lab, &principal, webhook_id, body).await?;
    state.deliveries.notify_one();
    Ok((StatusCode::ACCEPTED, Json(Webhook::from(&stored))))
}

/// The query of the delivery log.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct DeliveriesParams {
    /// How many attempts, newest first.
    #[param(value_type = Option<u32>, minimum = 1, maximum = 500, default = 50)]
    limit: Option<String>,
}

/// An endpoint's delivery log.
#[derive(Debug, Serialize, ToSchema)]
pub struct DeliveryList {
    /// Its attempts, newest first (the newest 1 000 are kept).
    pub items: Vec<Delivery>,
}

/// `GET /v1/webhooks/{webhook_id}/deliveries`.
#[utoipa::path(
    get,
    path = "/v1/webhooks/{webhook_id}/deliveries",
    tag = "webhooks",
    operation_id = "listWebhookDeliveries",
    summary = "An endpoint's delivery attempts, newest first (admin).",
    params(("webhook_id" = crate::domain::schema::Identifier, Path, description = "The endpoint's id."),
        DeliveriesParams),
    responses(
        (status = 200, description = "The attempts.", body = DeliveryList),
        (status = 400, response = super::openapi::BadRequest),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn deliveries(
    State(state): State<AppState>,
    principal: Principal,
    Path(webhook_id): Path<String>,
    Params(q): Params<DeliveriesParams>,
) -> Result<Json<DeliveryList>, Problem> {
    require(&principal, Role::Admin)?;
    path_identifier(&webhook_id, "webhook")?;
    let limit = super::query::limit(q.limit.as_deref())?.min(MAX_PAGE);
    webhooks::get(&state.lab, webhook_id.clone()).await?;
    let items = crate::store::Webhooks::deliveries(state.store.as_ref(), webhook_id, limit)
        .await
        .map_err(crate::app::Error::Store)?;
    Ok(Json(DeliveryList { items }))
}
