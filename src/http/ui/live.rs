//! `GET /ui/events`: the pages' own event stream, for the script that keeps
//! the fleet and a sensor's page current (`assets/live.js`). The same
//! events as `GET /v1/events` ([`crate::http::sse`]), authenticated by the
//! session cookie (a browser's `EventSource` sends no `Authorization`
//! header), unnamed so that one `message` listener sees every type,
//! resumed by `Last-Event-ID` when the browser reconnects, and ended when
//! the session ends.

use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::Response;
use serde::Deserialize;

use super::UiError;
use super::viewer::Viewer;
use crate::domain::auth::Role;
use crate::domain::events::Filter;
use crate::http::AppState;
use crate::http::auth::require;
use crate::http::query::Params;
use crate::http::sse::{self, Holder, Named};

/// The query: one sensor's events, or every event (the fleet).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LiveQuery {
    /// Only this sensor's events.
    sensor_id: Option<String>,
}

/// `GET /ui/events`.
pub async fn stream(
    State(state): State<AppState>,
    viewer: Viewer,
    headers: HeaderMap,
    Params(q): Params<LiveQuery>,
) -> Result<Response, UiError> {
    require(&viewer.principal, Role::Reader)?;
    let filter = Filter {
        sensors: q.sensor_id.into_iter().collect(),
        types: Vec::new(),
    };
    let resume = sse::resume(&headers, None)?;
    let holder = Holder::Session(viewer.id_hash);
    Ok(sse::respond(&state, holder, filter, resume, Named::No).await?)
}
