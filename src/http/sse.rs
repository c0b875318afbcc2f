//! A stream of live events as server-sent events, shared by `GET
//! /v1/events` ([`super::events`]) and the pages' own stream (`GET
//! /ui/events`, [`super::ui::live`]): a client's catch-up from the audit
//! trail after the id it resumes from, then the feed every replica's acts
//! reach ([`crate::app::events::Feed`]). A client that falls
//! [`crate::app::events::BUFFER`] events behind is disconnected — it never
//! slows an act — and resumes with its last id. A stream outlives neither
//! its token nor its session: who holds it ([`Holder`]) is looked at again
//! every `--events-heartbeat`, and the stream ends once the token is
//! revoked or the session ended or expired.

use std::collections::VecDeque;
use std::sync::Arc;

use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::sse::{Event as Sse, KeepAlive};
use axum::response::{IntoResponse, Response};
use futures_util::stream;

use super::AppState;
use super::auth::still_valid;
use super::problem::Problem;
use crate::app::events::{self, Next, Subscription};
use crate::domain::auth::{ENV_ADMIN, Principal};
use crate::domain::events::{Filter, LiveEvent};
use crate::domain::timestamp::Timestamp;

/// Who holds a stream, looked at again every `--events-heartbeat`.
#[derive(Clone, Debug)]
pub enum Holder {
    /// A bearer token's principal (`GET /v1/events`): the stream ends when
    /// the token is revoked (the configured admin token lasts as long as
    /// the process).
    Token(Principal),
    /// A page session, by the SHA-256 of its cookie (`GET /ui/events`):
    /// the stream ends when the session is signed out, expires, or its
    /// token is revoked.
    Session([u8; 32]),
}

impl Holder {
    /// Whether the holder may still read the stream; an unreadable store
    /// says no (the client resumes with its last id once it can).
    async fn still_allowed(&self, state: &AppState) -> bool {
        match self {
            Holder::Token(p) if p.id == ENV_ADMIN => true,
            Holder::Token(p) => {
                let Ok(id) = uuid::Uuid::try_parse(&p.id) else {
                    return false;
                };
                matches!(state.store.token(id).await, Ok(Some(t)) if t.revoked_at.is_none())
            }
            Holder::Session(hash) => match state.store.session(*hash).await {
                Ok(Some(s)) if s.expires_at > Timestamp::now() => matches!(
                    still_valid(state, &s.principal, &s.credential_hash).await,
                    Ok(Some(_))
                ),
                _ => false,
            },
        }
    }
}

/// Whether each event carries its type as the SSE `event:` field. A
/// browser's `EventSource` hands named events only to listeners of that
/// name; the pages' script listens to every event, so its stream is not
/// named (the type is in the data either way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Named {
    /// `event: <type>` on every event.
    Yes,
    /// No `event:` field: every event is a `message`.
    No,
}

/// Where a client resumes: after `Last-Event-ID` (a browser's
/// `EventSource` sends it when it reconnects), else after `after` (a first
/// connection's query), else nowhere (the newest event); with the name of
/// whichever gave it.
pub fn resume(
    headers: &HeaderMap,
    after: Option<&str>,
) -> Result<Option<(i64, &'static str)>, Problem> {
    let (raw, name) = match headers.get("last-event-id") {
        Some(v) => (
            v.to_str().map_err(|_| {
                Problem::bad_parameter("Last-Event-ID", "must be an event id (ASCII digits)")
            })?,
            "Last-Event-ID",
        ),
        None => match after {
            Some(a) => (a, "after"),
            None => return Ok(None),
        },
    };
    let id = raw
        .trim()
        .parse::<i64>()
        .ok()
        .filter(|n| *n >= 0)
        .ok_or_else(|| {
            Problem::bad_parameter(name, "must be an event id (a whole number, 0 or more)")
        })?;
    Ok(Some((id, name)))
}

/// The stream of the events `filter` admits to `holder`, after `resume`
/// (an id and the name of the parameter or header that gave it, for a
/// refusal) or from the newest event. An id past the newest is a 400: the
/// client's ids come from another database.
pub async fn respond(
    state: &AppState,
    holder: Holder,
    filter: Filter,
    resume: Option<(i64, &'static str)>,
    named: Named,
) -> Result<Response, Problem> {
    let feed = state.events.clone();
    let subscription = feed.subscribe().await?;
    let head = feed.head().await?;
    let cursor = match resume {
        Some((id, name)) if id > head => {
            return Err(Problem::bad_parameter(
                name,
                format!("is {id}, past the newest event ({head}): was the database replaced?"),
            ));
        }
        Some((id, _)) => id,
        None => head,
    };
    let client = Client {
        feed,
        subscription,
        filter,
        cursor,
        catching_up: resume.is_some(),
        pending: VecDeque::new(),
        holder,
        state: state.clone(),
        recheck: {
            let every = state.web.events_heartbeat;
            let mut i = tokio::time::interval_at(tokio::time::Instant::now() + every, every);
            i.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            i
        },
        _gauge: Gauge::new(),
    };
    let events = stream::unfold(client, move |mut c| async move {
        let e = c.next().await?;
        let mut sse = Sse::default()
            .id(e.seq.to_string())
            .data(serde_json::to_string(&*e).unwrap_or_default());
        if named == Named::Yes {
            sse = sse.event(e.kind.as_str());
        }
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
    holder: Holder,
    state: AppState,
    /// When to look at the holder again.
    recheck: tokio::time::Interval,
    _gauge: Gauge,
}

impl Client {
    /// The next event to send; `None` ends the stream (shutdown, a client
    /// too slow, the trail unreadable: the client resumes with its last id;
    /// a holder no longer allowed).
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
            let next = tokio::select! {
                next = self.subscription.next() => next,
                _ = self.recheck.tick() => {
                    if self.holder.still_allowed(&self.state).await {
                        continue;
                    }
                    tracing::info!("live events: a stream's token or session ended; the stream ends");
                    metrics::counter!("accelcal_events_clients_ended_total").increment(1);
                    return None;
                }
            };
            match next {
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
