//! The live events' feed (issue 47 item 2): one poller per replica reads
//! the audit trail's newly sealed entries — every `--events-poll-ms`, and
//! as soon as the store says this replica's own acts joined the chain
//! ([`crate::store::Audit::trail_grew`]) — and hands each event
//! ([`LiveEvent`]) to every subscriber on this replica; a subscriber that
//! resumes reads what it missed from the trail itself.
//!
//! **Order and gaps.** Events are the trail's entries, sealed in one total
//! order shared by every replica of a database (`seq`); the poller reads
//! after the last it handed on, so every replica's subscribers see every
//! replica's events, in `seq` order. A subscriber first subscribes, then
//! takes its cursor — the id it resumes after, or the trail's head — and
//! reads the trail after it until it is caught up; from then on it takes
//! the poller's events after its cursor. The poller's start is awaited
//! before anyone subscribes, so an event the poller did not hand to a
//! subscriber was sealed before its subscription, at or below its cursor,
//! or read by its catch-up.
//!
//! **Slow subscribers.** The poller never waits for a subscriber: each has
//! a buffer of [`BUFFER`] events (a broadcast channel), and one that falls
//! further behind is disconnected ([`Next::Lagged`]) — it reconnects with
//! its last id and catches up from the trail. An act never waits for an
//! event: events are read after the acts' commits.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;

use tokio::sync::{OnceCell, broadcast, watch};

use crate::domain::events::{Filter, LiveEvent};
use crate::domain::review::Basis;
use crate::store::{Store, StoreError};

/// Events a subscriber may fall behind the poller before it is
/// disconnected.
pub const BUFFER: usize = 1024;

/// Entries read from the trail at once.
pub const PAGE: usize = 500;

/// How often the poller looks for newly sealed entries, by default (other
/// replicas' acts; this replica's wake it at once).
pub const POLL: Duration = Duration::from_millis(200);

/// The least time between two looks: under a stream of acts, one look
/// reads what several commits sealed.
pub const GAP: Duration = Duration::from_millis(5);

/// The feed of a replica: the trail's events, handed on as they are sealed.
pub struct Feed {
    store: Arc<dyn Store>,
    /// The service's basis, on which events tell what the coefficients did.
    basis: Basis,
    poll: Duration,
    tx: broadcast::Sender<Arc<LiveEvent>>,
    /// The last `seq` the poller has handed on.
    head: Arc<AtomicI64>,
    started: OnceCell<()>,
    closed: watch::Sender<bool>,
}

/// What a subscriber's next wait came to.
pub enum Next {
    /// An event after its cursor.
    Event(Arc<LiveEvent>),
    /// It fell more than [`BUFFER`] events behind: disconnect it.
    Lagged,
    /// The service is shutting down.
    Closed,
}

/// A subscription: the poller's events, from the moment it was taken.
pub struct Subscription {
    rx: broadcast::Receiver<Arc<LiveEvent>>,
    closed: watch::Receiver<bool>,
}

impl Subscription {
    /// The next event the poller hands on, or why there is none.
    pub async fn next(&mut self) -> Next {
        if *self.closed.borrow() {
            return Next::Closed;
        }
        tokio::select! {
            got = self.rx.recv() => match got {
                Ok(e) => Next::Event(e),
                Err(broadcast::error::RecvError::Lagged(_)) => Next::Lagged,
                Err(broadcast::error::RecvError::Closed) => Next::Closed,
            },
            _ = self.closed.changed() => Next::Closed,
        }
    }
}

impl Feed {
    /// A feed over `store` that looks for new entries every `poll` once
    /// someone subscribes; its events tell what the coefficients did on
    /// `basis`.
    pub fn new(store: Arc<dyn Store>, poll: Duration, basis: Basis) -> Feed {
        Feed {
            store,
            basis,
            poll,
            tx: broadcast::channel(BUFFER).0,
            head: Arc::new(AtomicI64::new(0)),
            started: OnceCell::new(),
            closed: watch::channel(false).0,
        }
    }

    /// Subscribes, starting the poller first if it is not running: from
    /// the trail's head as it is now.
    pub async fn subscribe(&self) -> Result<Subscription, StoreError> {
        self.started
            .get_or_try_init(|| async {
                self.head
                    .store(self.store.audit_head().await?, Ordering::SeqCst);
                tokio::spawn(poller(
                    self.store.clone(),
                    self.basis,
                    self.store.trail_grew(),
                    self.poll,
                    self.tx.clone(),
                    self.head.clone(),
                    self.closed.subscribe(),
                ));
                Ok::<(), StoreError>(())
            })
            .await?;
        Ok(Subscription {
            rx: self.tx.subscribe(),
            closed: self.closed.subscribe(),
        })
    }

    /// The trail's head: the last event's id (0 before any).
    pub async fn head(&self) -> Result<i64, StoreError> {
        self.store.audit_head().await
    }

    /// The events after `after` that `filter` admits, read from the trail,
    /// at most [`PAGE`] entries' worth, and the last `seq` read (`after`
    /// when there was none: caught up).
    pub async fn since(
        &self,
        after: i64,
        filter: &Filter,
    ) -> Result<(Vec<LiveEvent>, i64), StoreError> {
        since(self.store.as_ref(), self.basis, after, filter, PAGE).await
    }

    /// Ends every subscription and the poller (the service is stopping).
    pub fn close(&self) {
        self.closed.send_replace(true);
    }

    /// Subscribers on this replica now.
    pub fn subscribers(&self) -> usize {
        self.tx.receiver_count()
    }
}

/// The events after `after` that `filter` admits, read from the trail of
/// `store`, at most `page` entries' worth, and the last `seq` read
/// (`after` when there was none: caught up); each telling what the
/// coefficients did on `basis`.
pub async fn since(
    store: &dyn Store,
    basis: Basis,
    after: i64,
    filter: &Filter,
    page: usize,
) -> Result<(Vec<LiveEvent>, i64), StoreError> {
    let entries = store.sealed_after(after, page).await?;
    let last = entries.last().map_or(after, |e| e.seq);
    let events = events(store, basis, &entries).await?;
    Ok((
        events.into_iter().filter(|e| filter.admits(e)).collect(),
        last,
    ))
}

/// The events of `entries`, each with its sensor: the one the entry names,
/// else its calibration's.
async fn events(
    store: &dyn Store,
    basis: Basis,
    entries: &[crate::domain::audit::Entry],
) -> Result<Vec<LiveEvent>, StoreError> {
    let mut out = Vec::with_capacity(entries.len());
    for e in entries {
        let Some(mut event) = LiveEvent::from_entry(e, basis) else {
            continue;
        };
        if let Some(id) = event.needs_sensor() {
            event.sensor_id = store.calibration_summary(id).await?.map(|c| c.sensor_id);
        }
        out.push(event);
    }
    Ok(out)
}

/// Waits until the store says the trail grew ([`Audit::trail_grew`](crate::store::Audit::trail_grew));
/// forever when it cannot tell, or has closed.
pub(crate) async fn grown(rx: &mut Option<watch::Receiver<u64>>) {
    if let Some(r) = rx
        && r.changed().await.is_ok()
    {
        return;
    }
    std::future::pending().await
}

/// Hands on every entry sealed after `head`, every `poll` and whenever
/// the store says the trail grew (this replica's own acts, at once), until
/// closed.
async fn poller(
    store: Arc<dyn Store>,
    basis: Basis,
    mut grew: Option<watch::Receiver<u64>>,
    poll: Duration,
    tx: broadcast::Sender<Arc<LiveEvent>>,
    head: Arc<AtomicI64>,
    mut closed: watch::Receiver<bool>,
) {
    let mut tick = tokio::time::interval(poll);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            () = grown(&mut grew) => {}
            _ = closed.changed() => return,
        }
        let looked = tokio::time::Instant::now();
        loop {
            let after = head.load(Ordering::SeqCst);
            let entries = match store.sealed_after(after, PAGE).await {
                Ok(entries) => entries,
                Err(e) => {
                    tracing::warn!(error = %e, "live events: the trail could not be read");
                    break;
                }
            };
            let Some(last) = entries.last().map(|e| e.seq) else {
                break;
            };
            match events(store.as_ref(), basis, &entries).await {
                Ok(found) => {
                    head.store(last, Ordering::SeqCst);
                    metrics::counter!("accelcal_events_total").increment(found.len() as u64);
                    for e in found {
                        // No subscriber is no error.
                        let _ = tx.send(Arc::new(e));
                    }
                }
                Err(e) => {
                    tracing::warn!(error = %e, "live events: a calibration could not be read");
                    break;
                }
            }
            if entries.len() < PAGE {
                break;
            }
        }
        tokio::time::sleep_until(looked + GAP).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::audit::Actor;
    use crate::domain::events::EventType;
    use crate::domain::timestamp::Timestamp;
    use crate::store::audit::retyped;

    /// A feed over a fresh SQLite file, polling every 10 ms.
    fn feed() -> (tempfile::TempDir, Arc<dyn Store>, Feed) {
        let dir = tempfile::tempdir().unwrap();
        let store: Arc<dyn Store> =
            Arc::new(crate::store::sqlite::SqliteStore::open(dir.path().join("f.db")).unwrap());
        let feed = Feed::new(store.clone(), Duration::from_millis(10), Basis::NotRejected);
        (dir, store, feed)
    }

    /// `n` acts that are events (sensors retyped), recorded in the trail.
    async fn retype(store: &dyn Store, n: usize) {
        let at = Timestamp::parse("2026-11-28T08:00:00Z").unwrap();
        let acts = (0..n)
            .map(|i| retyped(&format!("S-{i}"), "A", at, Actor::service()))
            .collect();
        store.record(acts).await.unwrap();
    }

    /// A subscriber gets every event after its subscription, in order; one
    /// that does not read while more than [`BUFFER`] are handed on is told
    /// it lagged (the poller never waited for it), and catches up from the
    /// trail.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn subscribers_follow_the_trail_and_a_slow_one_lags() {
        let (_dir, store, feed) = feed();
        retype(store.as_ref(), 3).await; // before anyone subscribed
        let mut reading = feed.subscribe().await.unwrap();
        let mut stalled = feed.subscribe().await.unwrap();
        let start = feed.head().await.unwrap();
        retype(store.as_ref(), 2).await;
        for expected in [start + 1, start + 2] {
            let Next::Event(e) = reading.next().await else {
                panic!("an event")
            };
            assert_eq!((e.seq, e.kind), (expected, EventType::SensorRetyped));
        }
        retype(store.as_ref(), BUFFER + 10).await;
        let mut got = 0;
        while got < BUFFER + 10 {
            match tokio::time::timeout(Duration::from_secs(10), reading.next()).await {
                Ok(Next::Event(_)) => got += 1,
                Ok(Next::Lagged) => break, // read too slowly here too: allowed
                _ => panic!("the reading subscriber stopped getting events"),
            }
        }
        assert!(matches!(stalled.next().await, Next::Lagged));
        // What it missed is in the trail, after its cursor.
        let (missed, last) = feed.since(start, &Filter::default()).await.unwrap();
        assert_eq!(missed.len(), PAGE);
        assert_eq!(missed[0].seq, start + 1);
        assert_eq!(last, start + PAGE as i64);
        feed.close();
        assert!(matches!(reading.next().await, Next::Closed));
    }
}
