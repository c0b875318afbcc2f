//! `GET /v1/events`: the live events as server-sent events (issue 47
//! item 2), for dashboards — readers and up.
//!
//! Each event is sent as
//!
//! ```text
//! id: <seq>
//! event: <type>
//! data: <the event as JSON, LiveEvent>
//! ```
//!
//! with a comment line (`:`) every `--events-heartbeat` (15 s) while
//! nothing happens, so that proxies keep the stream open and a client
//! notices a dead one. `Last-Event-ID` (a browser's `EventSource` sends it
//! when it reconnects), or `after` on a first connection, resumes after
//! that id: the events are the audit trail's entries, kept for good, so
//! any id the service sent can be resumed from. Without either the stream
//! starts at the newest event. The stream itself (catch-up, a slow client
//! disconnected) is [`super::sse`]'s.

use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::Response;
use serde::Deserialize;
use utoipa::IntoParams;

use super::AppState;
use super::auth::require;
use super::problem::Problem;
use super::query::Params;
use super::sse::{self, Holder, Named};
use crate::domain::auth::{Principal, Role};
use crate::domain::events::{EventType, Filter, LiveEvent};

/// Most sensors or types one filter names.
const MAX_NAMES: usize = 100;

/// The query of `GET /v1/events`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct EventsParams {
    /// Only events of these sensors (comma-separated).
    #[param(value_type = Option<String>, min_length = 1, max_length = 8000)]
    sensor_id: Option<String>,
    /// Only events of these types (comma-separated): `calibration.stored`,
    /// `calibration.approved`, `calibration.rejected`,
    /// `calibration.withdrawn`, `calibration.superseded`,
    /// `calibration.held`, `calibration.released`, `certificate.issued`,
    /// `certificate.amended`, `sensor.retyped`, `standard.nonconformity`.
    #[param(value_type = Option<String>, min_length = 1, max_length = 2000)]
    r#type: Option<String>,
    /// Resume after this event id (as `Last-Event-ID`, which wins).
    #[param(value_type = Option<String>, pattern = "^[0-9]{1,18}$")]
    after: Option<String>,
}

/// The names of a comma-separated list, each non-empty, at most
/// [`MAX_NAMES`].
fn names(name: &str, raw: Option<&str>) -> Result<Vec<String>, Problem> {
    let Some(raw) = raw else {
        return Ok(Vec::new());
    };
    let list: Vec<String> = raw.split(',').map(str::to_owned).collect();
    if list.iter().any(String::is_empty) || list.len() > MAX_NAMES {
        return Err(Problem::bad_parameter(
            name,
            format!("must be 1 to {MAX_NAMES} comma-separated names, none empty"),
        ));
    }
    Ok(list)
}

impl EventsParams {
    fn filter(&self) -> Result<Filter, Problem> {
        let types = names("type", self.r#type.as_deref())?
            .iter()
            .map(|t| {
                EventType::parse(t).ok_or_else(|| {
                    let known: Vec<&str> = EventType::ALL.iter().map(|t| t.as_str()).collect();
                    Problem::bad_parameter(
                        "type",
                        format!(
                            "names `{}`, which is no event type; the types are {}",
                            crate::domain::text::echo(t),
                            known.join(", ")
                        ),
                    )
                })
            })
            .collect::<Result<_, _>>()?;
        Ok(Filter {
            sensors: names("sensor_id", self.sensor_id.as_deref())?,
            types,
        })
    }
}

/// `GET /v1/events`.
#[utoipa::path(
    get,
    path = "/v1/events",
    tag = "events",
    operation_id = "streamEvents",
    summary = "Live events as server-sent events (reader and up).",
    description = "One event per act a reader or a control system would act on: a \
        calibration stored, approved, rejected, withdrawn, superseded, held or released; \
        a certificate issued or amended; a sensor retyped; a standard's nonconformity. \
        Each is sent with `id:` its sequence number (the audit entry it is), `event:` \
        its type and `data:` the event as JSON (`LiveEvent`). `Last-Event-ID` (or \
        `after`) resumes after that id; a heartbeat comment keeps the stream open.",
    params(EventsParams,
        ("Last-Event-ID" = Option<String>, Header, description = "Resume after this event id.")),
    responses(
        (status = 200, description = "The stream of events.", content_type = "text/event-stream", body = LiveEvent),
        (status = 400, response = super::openapi::BadRequest),
        (status = 403, response = super::openapi::Forbidden),
        super::openapi::Always,
    )
)]
pub async fn stream(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    Params(q): Params<EventsParams>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let filter = q.filter()?;
    let resume = sse::resume(&headers, q.after.as_deref())?;
    sse::respond(&state, Holder::Token(principal), filter, resume, Named::Yes).await
}
