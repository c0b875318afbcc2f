//! The listener that keeps a replica's [`SensorCache`] and [`TokenCache`]
//! in step with every other replica's writes.
//!
//! One connection of its own runs `LISTEN accelcal_sensors` and `LISTEN
//! accelcal_tokens`; the trigger of migration 0002 notifies the first with
//! a sensor's id whenever a transaction that changed the sensor's row
//! commits, whichever process ran it, and that of migration 0004 the second
//! with a token's id when a token changes (is revoked). Each notification
//! drops that sensor's or token's entry. What follows about the cache holds
//! for both. The cache is emptied and
//! made live only once `LISTEN` has taken effect, and made not live (so
//! bypassed) as soon as the connection fails or stops answering the
//! heartbeat; the listener then reconnects with a growing pause (0.1 s to
//! 5 s). A notification can thus be missed only while the cache is not used.
//!
//! **Echoes.** This replica's own batches are notified too, but the cache
//! has already applied them ([`SensorCache::write`]): dropping the entry
//! again would cost the sensor's next submission a read. So the writer,
//! before it commits a batch, records each sensor the batch changed with
//! the backend process id of its connection ([`Echoes::expect`]), and a
//! notification that matches such a record — same process, same sensor —
//! consumes it and drops nothing. PostgreSQL sends one notification per
//! sensor per transaction (identical payloads are folded), so one record
//! matches one notification. A record whose notification cannot come — the
//! commit failed ([`Echoes::forget`]), or the listener was not listening —
//! must not swallow a later notification: records are cleared whenever the
//! listener (re)connects, and a record forgotten after a commit whose
//! outcome is unknown lets that notification drop the entry (the write's
//! own end drops it too). The connection holds its process id for as long
//! as it holds the transaction, so no other session's notification can
//! match a record before its own arrives.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio_postgres::AsyncMessage;

use super::connect;
use crate::store::StoreError;
use crate::store::cache::{SensorCache, TokenCache, tokens};

/// The channel the trigger notifies.
pub const CHANNEL: &str = "accelcal_sensors";

/// The listener's connection as `pg_stat_activity` names it.
pub const APPLICATION_NAME: &str = "accelcal-cache-listener";

/// How often the listener checks that its connection still answers, and
/// how long it waits for the answer.
const HEARTBEAT: Duration = Duration::from_secs(2);

/// One notification: the notifying backend, the channel's kind, the id.
struct Note {
    pid: i32,
    token: bool,
    id: String,
}

/// Echoes recorded at most; beyond, they are all cleared (their
/// notifications then drop entries: a read each, never a stale answer).
const ECHOES: usize = 4096;

/// The notifications this replica's own commits will cause: how many are
/// expected per (backend process id, sensor).
#[derive(Debug, Default)]
pub struct Echoes {
    expected: Mutex<HashMap<(i32, String), u32>>,
}

impl Echoes {
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<(i32, String), u32>> {
        self.expected.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A transaction of backend `pid` that changed `sensors` is about to
    /// commit.
    pub fn expect(&self, pid: i32, sensors: &[String]) {
        let mut m = self.lock();
        for s in sensors {
            if m.len() >= ECHOES {
                m.clear();
            }
            *m.entry((pid, s.clone())).or_default() += 1;
        }
    }

    /// That transaction did not commit (or may not have): its notifications
    /// are not expected.
    pub fn forget(&self, pid: i32, sensors: &[String]) {
        let mut m = self.lock();
        for s in sensors {
            let key = (pid, s.clone());
            if let Some(n) = m.get_mut(&key) {
                *n -= 1;
                if *n == 0 {
                    m.remove(&key);
                }
            }
        }
    }

    /// Whether the notification of `sensor_id` by backend `pid` is an
    /// expected echo (then consumed).
    fn take(&self, pid: i32, sensor_id: &str) -> bool {
        let mut m = self.lock();
        // A tuple key is looked up by value: one copy of the id per notification.
        let key = (pid, sensor_id.to_owned());
        match m.get_mut(&key) {
            None => false,
            Some(n) => {
                *n -= 1;
                if *n == 0 {
                    m.remove(&key);
                }
                true
            }
        }
    }

    fn clear(&self) {
        self.lock().clear();
    }

    /// Echoes expected now.
    pub fn len(&self) -> usize {
        self.lock().values().map(|n| *n as usize).sum()
    }

    /// Whether none is expected.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Starts the listener for the database at `url`; it runs until aborted.
pub fn spawn(
    url: String,
    cache: Arc<SensorCache>,
    tokens: Arc<TokenCache>,
    echoes: Arc<Echoes>,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut pause = Duration::from_millis(100);
        loop {
            let outcome = listen(&url, &cache, &tokens, &echoes).await;
            cache.reset(false);
            tokens.reset(false);
            match outcome {
                Ok(()) => pause = Duration::from_millis(100),
                Err(e) => {
                    tracing::warn!(error = %e.chain(), "the cache's listener lost PostgreSQL; reads bypass the cache until it is back");
                }
            }
            tokio::time::sleep(pause).await;
            pause = (pause * 2).min(Duration::from_secs(5));
        }
    })
}

/// One connection's life: connect, `LISTEN`, go live, drop what is
/// notified; returns when the connection ends or stops answering.
async fn listen(
    url: &str,
    cache: &SensorCache,
    tokens: &TokenCache,
    echoes: &Echoes,
) -> Result<(), StoreError> {
    let unavailable = |e: tokio_postgres::Error| StoreError::Unavailable(Box::new(e));
    let (mut config, tls) = connect::config(url)?;
    config.application_name(APPLICATION_NAME);
    let (client, mut connection) = config.connect(tls).await.map_err(unavailable)?;
    let (tx, mut notes) = tokio::sync::mpsc::unbounded_channel();
    // The connection must be polled for the client's queries to complete;
    // its notifications come out of the same poll.
    let driver = tokio::spawn(async move {
        loop {
            match std::future::poll_fn(|cx| connection.poll_message(cx)).await {
                Some(Ok(AsyncMessage::Notification(n))) => {
                    let note = Note {
                        pid: n.process_id(),
                        token: n.channel() == tokens::CHANNEL,
                        id: n.payload().to_owned(),
                    };
                    if tx.send(note).is_err() {
                        return Ok(());
                    }
                }
                Some(Ok(_)) => {}
                Some(Err(e)) => return Err(e),
                None => return Ok(()),
            }
        }
    });
    let outcome = async {
        client
            .batch_execute(&format!("LISTEN {CHANNEL}; LISTEN {}", tokens::CHANNEL))
            .await
            .map_err(unavailable)?;
        // From here on every commit is notified: what was cached before
        // goes, and the cache may be used.
        echoes.clear();
        cache.reset(true);
        tokens.reset(true);
        tracing::info!("the sensor cache listens to PostgreSQL");
        let mut beat = tokio::time::interval(HEARTBEAT);
        loop {
            tokio::select! {
                note = notes.recv() => match note {
                    Some(Note { token: true, id, .. }) => match uuid::Uuid::try_parse(&id) {
                        Ok(id) => tokens.invalidate(id),
                        // Not a token's id: nothing cached can match it, but
                        // be safe.
                        Err(_) => tokens.reset(true),
                    },
                    Some(Note { pid, id, .. }) => {
                        if !echoes.take(pid, &id) {
                            cache.invalidate(&id);
                        }
                    }
                    None => return Ok(()),
                },
                _ = beat.tick() => {
                    match tokio::time::timeout(HEARTBEAT, client.simple_query("")).await {
                        Ok(Ok(_)) => {}
                        Ok(Err(e)) => return Err(unavailable(e)),
                        Err(_) => {
                            return Err(StoreError::Unavailable(
                                "the listener's connection stopped answering".into(),
                            ));
                        }
                    }
                }
            }
        }
    }
    .await;
    cache.reset(false);
    tokens.reset(false);
    echoes.clear();
    driver.abort();
    outcome
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sensors(ids: &[&str]) -> Vec<String> {
        ids.iter().map(|s| (*s).to_owned()).collect()
    }

    /// One record matches one notification of that process and sensor,
    /// and nothing else.
    #[test]
    fn an_echo_is_its_process_and_sensor_once() {
        let e = Echoes::default();
        e.expect(7, &sensors(&["A", "B"]));
        assert!(!e.take(8, "A"), "another process's notification");
        assert!(!e.take(7, "C"), "another sensor");
        assert!(e.take(7, "A"));
        assert!(!e.take(7, "A"), "consumed");
        assert_eq!(e.len(), 1);
        // Two batches of one connection before their notifications arrive.
        e.expect(7, &sensors(&["B"]));
        assert!(e.take(7, "B") && e.take(7, "B"));
        assert!(!e.take(7, "B"));
        assert!(e.is_empty());
    }

    /// A commit that failed leaves nothing to match; neither does a
    /// (re)connection of the listener.
    #[test]
    fn forgotten_and_cleared_echoes_match_nothing() {
        let e = Echoes::default();
        e.expect(7, &sensors(&["A", "B"]));
        e.expect(7, &sensors(&["A"]));
        e.forget(7, &sensors(&["A", "B"]));
        assert!(!e.take(7, "B"));
        assert!(e.take(7, "A"), "the other batch's echo stays");
        e.forget(7, &sensors(&["A"]));
        assert!(e.is_empty(), "forgetting what is not expected is a no-op");
        e.expect(7, &sensors(&["A"]));
        e.clear();
        assert!(!e.take(7, "A"));
    }

    /// At most [`ECHOES`] are kept: beyond, all go (their notifications
    /// then drop entries, which costs reads, not answers).
    #[test]
    fn echoes_are_bounded() {
        let e = Echoes::default();
        let many: Vec<String> = (0..ECHOES + 10).map(|i| format!("S{i}")).collect();
        e.expect(1, &many);
        assert!(e.len() <= ECHOES);
        assert!(e.take(1, &many[ECHOES + 9]), "the latest are kept");
    }
}
