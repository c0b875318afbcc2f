//! `GET /ui/events`: the pages' own event stream, for the script that keeps
//! the fleet and a sensor's page current (`assets/live.js`). The same
//! events as `GET /v1/events` ([`crate::http::sse`]), authenticated by the
//! session cookie (a browser's `EventSource` sends no `Authorization`
//! header), unnamed so that one `message` listener sees every type,
//! resumed by `Last-Event-ID` when the browser reconnects, and ended when
//! the session ends.
//!
//! Without a session (none, expired, signed out, its token revoked) the
//! stream answers `204 No Content`, not the pages' redirect to the sign-in
//! form: any status but 200 makes a browser's `EventSource` stop for good
//! (WHATWG HTML, server-sent events: "fail the connection"), where the
//! form's HTML would be refused with an error in the console. The script
//! then says the updates stopped; the page itself, reloaded, asks to sign
//! in, saying why (the stream leaves a dead session for the page to end).

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;

use super::UiError;
use super::viewer;
use crate::domain::auth::Role;
use crate::domain::events::Filter;
use crate::http::AppState;
use crate::http::auth::require;
use crate::http::problem::Problem;
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
    headers: HeaderMap,
    query: Result<Params<LiveQuery>, Problem>,
) -> Result<Response, UiError> {
    // The session first, as every page asks for it before its query.
    let Ok(viewer) = viewer::look(&headers, &state).await? else {
        return Ok(no_session());
    };
    require(&viewer.principal, Role::Reader)?;
    let Params(q) = query?;
    let filter = Filter {
        sensors: q.sensor_id.into_iter().collect(),
        types: Vec::new(),
    };
    let resume = sse::resume(&headers, None)?;
    let holder = Holder::Session(viewer.id_hash);
    Ok(sse::respond(&state, holder, filter, resume, Named::No).await?)
}

/// The answer to a stream asked for without a live session: `204`, never
/// cached, which ends the browser's reconnecting.
fn no_session() -> Response {
    let mut res = StatusCode::NO_CONTENT.into_response();
    res.headers_mut()
        .insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    res
}
