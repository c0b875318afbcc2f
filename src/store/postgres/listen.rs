//! The listener that keeps a replica's [`SensorCache`] in step with every
//! other replica's writes.
//!
//! One connection of its own runs `LISTEN accelcal_sensors`; the trigger of
//! migration 0002 notifies that channel with a sensor's id whenever a
//! transaction that changed the sensor's row commits, whichever process ran
//! it. Each notification drops that sensor's entry. The cache is emptied and
//! made live only once `LISTEN` has taken effect, and made not live (so
//! bypassed) as soon as the connection fails or stops answering the
//! heartbeat; the listener then reconnects with a growing pause (0.1 s to
//! 5 s). A notification can thus be missed only while the cache is not used.

use std::sync::Arc;
use std::time::Duration;

use tokio_postgres::AsyncMessage;

use super::connect;
use crate::store::StoreError;
use crate::store::cache::SensorCache;

/// The channel the trigger notifies.
pub const CHANNEL: &str = "accelcal_sensors";

/// The listener's connection as `pg_stat_activity` names it.
pub const APPLICATION_NAME: &str = "accelcal-cache-listener";

/// How often the listener checks that its connection still answers, and
/// how long it waits for the answer.
const HEARTBEAT: Duration = Duration::from_secs(2);

/// Starts the listener for the database at `url`; it runs until aborted.
pub fn spawn(url: String, cache: Arc<SensorCache>) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut pause = Duration::from_millis(100);
        loop {
            let outcome = listen(&url, &cache).await;
            cache.reset(false);
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
async fn listen(url: &str, cache: &SensorCache) -> Result<(), StoreError> {
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
                    if tx.send(n.payload().to_owned()).is_err() {
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
            .batch_execute(&format!("LISTEN {CHANNEL}"))
            .await
            .map_err(unavailable)?;
        // From here on every commit is notified: what was cached before
        // goes, and the cache may be used.
        cache.reset(true);
        tracing::info!("the sensor cache listens to PostgreSQL");
        let mut beat = tokio::time::interval(HEARTBEAT);
        loop {
            tokio::select! {
                note = notes.recv() => match note {
                    Some(sensor_id) => cache.invalidate(&sensor_id),
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
    driver.abort();
    outcome
}
