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
//! starts at the newest event. A client that falls [`events::BUFFER`]
//! events behind is disconnected and resumes with its last id.

use std::collections::VecDeque;
use std::sync::Arc;

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::sse::{Event as Sse, KeepAlive};
use axum::response::{IntoResponse, Response};
use futures_util::stream;
use serde::Deserialize;
use utoipa::IntoParams;

use super::AppState;
use super::auth::require;
use super::problem::Problem;
use super::query::Params;
use crate::app::events::{self, Next, Subscription};
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

/// An event id: a sequence number, 0 or more.
fn event_id(name: &str, raw: &str) -> Result<i64, Problem> {
    raw.trim()
        .parse::<i64>()
        .ok()
        .filter(|n| *n >= 0)
        .ok_or_else(|| {
            Problem::bad_parameter(name, "must be an event id (a whole number, 0 or more)")
        })
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
    let resume = match headers.get("last-event-id") {
        Some(v) => Some(event_id(
            "Last-Event-ID",
            v.to_str().map_err(|_| {
                Problem::bad_parameter("Last-Event-ID", "must be an event id (ASCII digits)")
            })?,
        )?),
        None => q
            .after
            .as_deref()
            .map(|a| event_id("after", a))
            .transpose()?,
    };
    let feed = state.events.clone();
    let subscription = feed.subscribe().await?;
    let head = feed.head().await?;
    let cursor = match resume {
        Some(id) if id > head => {
            return Err(Problem::bad_parameter(
                if headers.contains_key("last-event-id") {
                    "Last-Event-ID"
                } else {
                    "after"
                },
                format!("is {id}, past the newest event ({head}): was the database replaced?"),
            ));
        }
        Some(id) => id,
        None => head,
    };
    let client = Client {
        feed,
        subscription,
        filter,
        cursor,
        catching_up: resume.is_some(),
        pending: VecDeque::new(),
        _gauge: Gauge::new(),
    };
    let events = stream::unfold(client, |mut c| async move {
        let e = c.next().await?;
        let sse = Sse::default()
            .id(e.seq.to_string())
            .event(e.kind.as_str())
            .data(serde_json::to_string(&*e).unwrap_or_default());
        Some((Ok::<_, std::convert::Infallible>(sse), c))
    });
    let mut res = axum::response::Sse::new(events)
        .keep_alive(KeepAlive::new().interval(state.web.events_heartbeat))
        .into_response();
    let h = res.headers_mut();
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    h.insert("x-accel-buffering", HeaderValue::from_static("no"));
    Ok(res)
}

/// One client's stream: its catch-up from the trail, then the feed.
struct Client {
    feed: Arc<events::Feed>,
    subscription: Subscription,
    filter: Filter,
    /// The last event id it has been sent or passed over.
    cursor: i64,
    catching_up: bool,
    pending: VecDeque<LiveEvent>,
    _gauge: Gauge,
}

impl Client {
    /// The next event to send; `None` ends the stream (shutdown, a client
    /// too slow, the trail unreadable: the client resumes with its last id).
    async fn next(&mut self) -> Option<Arc<LiveEvent>> {
        loop {
            if let Some(e) = self.pending.pop_front() {
                return Some(Arc::new(e));
            }
            if self.catching_up {
                match self.feed.since(self.cursor, &self.filter).await {
                    Ok((_, last)) if last == self.cursor => self.catching_up = false,
                    Ok((found, last)) => {
                        self.cursor = last;
                        self.pending.extend(found);
                    }
                    Err(e) => {
                        tracing::warn!(error = %e, "live events: a catch-up failed");
                        return None;
                    }
                }
                continue;
            }
            match self.subscription.next().await {
                Next::Event(e) if e.seq > self.cursor => {
                    self.cursor = e.seq;
                    if self.filter.admits(&e) {
                        return Some(e);
                    }
                }
                Next::Event(_) => {}
                Next::Lagged => {
                    metrics::counter!("accelcal_events_clients_dropped_total").increment(1);
                    return None;
                }
                Next::Closed => return None,
            }
        }
    }
}

/// Counts a connected client in `accelcal_events_clients` while it lives.
struct Gauge;

impl Gauge {
    fn new() -> Gauge {
        metrics::gauge!("accelcal_events_clients").increment(1.0);
        Gauge
    }
}

impl Drop for Gauge {
    fn drop(&mut self) {
        metrics::gauge!("accelcal_events_clients").decrement(1.0);
    }
}
