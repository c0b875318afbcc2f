//! The HTTP API: state, router and the middleware stack.
//!
//! Routes are grouped by resource in the submodules; cross-cutting concerns
//! live in [`middleware`]; every error is a [`problem::Problem`].

pub mod calibrations;
pub mod compute;
pub mod extract;
pub mod health;
pub mod middleware;
pub mod page;
pub mod problem;
pub mod sensors;
pub mod tokens;

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::routing::{delete, get, post};
use tokio::sync::Semaphore;

use crate::store::Store;

/// Bounds on what one request may take.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Largest request body, in bytes.
    pub max_body_bytes: usize,
    /// Time allowed to receive a body.
    pub body_timeout: Duration,
    /// Time allowed for a whole request.
    pub request_timeout: Duration,
    /// Requests handled at once; more are answered 503.
    pub max_concurrent: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_body_bytes: 4 * 1024 * 1024,
            body_timeout: Duration::from_secs(30),
            request_timeout: Duration::from_secs(60),
            max_concurrent: 256,
        }
    }
}

/// What every handler can reach.
#[derive(Clone)]
pub struct AppState {
    /// The database.
    pub store: Arc<dyn Store>,
    /// `SHA-256` of the configured admin token, if one is configured.
    pub admin_token_hash: Option<[u8; 32]>,
    /// Request bounds.
    pub limits: Limits,
}

/// The whole application: routes, state and middleware.
pub fn router(state: AppState) -> Router {
    let semaphore = Arc::new(Semaphore::new(state.limits.max_concurrent));
    let v1 = Router::new()
        .route("/calibrations", post(calibrations::submit))
        .route("/calibrations/{id}", get(calibrations::get))
        .route(
            "/calibrations/{id}/submission",
            get(calibrations::submission),
        )
        .route("/sensors", get(sensors::list))
        .route("/sensors/{sensor_id}", get(sensors::get))
        .route("/sensors/{sensor_id}/calibrations", get(sensors::history))
        .route(
            "/sensors/{sensor_id}/coefficients",
            get(sensors::coefficients),
        )
        .route("/sensors/{sensor_id}/compensate", post(sensors::compensate))
        .route("/identify", post(compute::identify))
        .route("/fuse", post(compute::fuse))
        .route("/tokens", post(tokens::create).get(tokens::list))
        .route("/tokens/{id}", delete(tokens::revoke));
    Router::new()
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/openapi.yaml", get(health::openapi))
        .nest("/v1", v1)
        .fallback(health::not_found)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            middleware::deadline,
        ))
        .layer(axum::middleware::from_fn_with_state(
            semaphore,
            middleware::shed_load,
        ))
        .layer(axum::middleware::from_fn(middleware::outer))
        .with_state(state)
}

/// Checks, identifies and fuses a submission on the blocking pool (the
/// numerics of a large submission take milliseconds).
pub(crate) async fn evaluate(
    body: serde_json::Value,
    now: crate::timestamp::Timestamp,
) -> Result<crate::submission::Evaluated, problem::Problem> {
    tokio::task::spawn_blocking(move || crate::submission::evaluate(&body, now))
        .await
        .map_err(|e| {
            tracing::error!(error = %e, "evaluation task failed");
            problem::Problem::internal()
        })?
        .map_err(problem::Problem::validation)
}

/// The id in a path, or 404 when it is not one of ours.
pub(crate) fn path_id(raw: &str, what: &str) -> Result<uuid::Uuid, problem::Problem> {
    uuid::Uuid::try_parse(raw)
        .map_err(|_| problem::Problem::not_found(format!("no {what} with id `{raw}`")))
}
