//! Status changes by the clock (issue 47 item 2): a sensor whose due date
//! comes within 30 days becomes `due_soon`, one whose due date passes
//! `overdue`, with no act to say so. Each replica looks every
//! `--status-scan` seconds (60) for sensors whose status now differs from
//! the one last announced for their due date, and announces each change —
//! a `sensor.status` audit entry, so an event on the stream and to webhooks
//! — in one transaction that records it as announced
//! ([`crate::store::Sensors::announce_statuses`]): two replicas seeing the
//! same change announce it once. A change is therefore announced within
//! one scan interval of happening (and of a replica's start).
//!
//! Only the clock's statuses are announced: a calibration that makes a
//! sensor `ok` or `failed` is its own event (`calibration.stored`).

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::watch;

use crate::domain::status::Status;
use crate::domain::timestamp::Timestamp;
use crate::store::{Announced, SensorQuery, Store, StoreError};

/// How often a replica looks, by default.
pub const SCAN: Duration = Duration::from_secs(60);

/// Sensors read, and changes announced, at once.
const PAGE: usize = 500;

/// Starts this replica's scanner: a look at once, then every `every`,
/// until `closed` turns true (the task then ends, letting go of the store).
pub fn start(
    store: Arc<dyn Store>,
    every: Duration,
    mut closed: watch::Receiver<bool>,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(every);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                _ = tick.tick() => {}
                _ = closed.changed() => return,
            }
            match scan(store.as_ref(), Timestamp::now()).await {
                Ok(0) => {}
                Ok(n) => tracing::info!(sensors = n, "statuses changed by the clock announced"),
                Err(e) => tracing::warn!(error = %e, "the statuses could not be scanned"),
            }
        }
    })
}

/// Announces every sensor whose status at `now` is one the clock gives
/// (`due_soon`, `overdue`) and differs from the one announced for its due
/// date; answers how many.
pub async fn scan(store: &dyn Store, now: Timestamp) -> Result<usize, StoreError> {
    let mut current: Vec<Announced> = Vec::new();
    for status in [Status::DueSoon, Status::Overdue] {
        let mut after = None;
        loop {
            let q = SensorQuery {
                after: after.take(),
                status: Some(status),
                search: None,
                now,
                limit: PAGE,
            };
            let page = store.sensors(q).await?;
            let full = page.len() == PAGE;
            after = page.last().map(|s| s.sensor_id.clone());
            current.extend(
                page.into_iter()
                    .filter_map(|s| s.due_at.map(|due| (s.sensor_id, status, due))),
            );
            if !full {
                break;
            }
        }
    }
    let announced: HashMap<String, (Status, Timestamp)> = store
        .announced_statuses()
        .await?
        .into_iter()
        .map(|(id, s, due)| (id, (s, due)))
        .collect();
    let changed: Vec<Announced> = current
        .into_iter()
        .filter(|(id, s, due)| announced.get(id) != Some(&(*s, *due)))
        .collect();
    let mut n = 0;
    for chunk in changed.chunks(PAGE) {
        n += store.announce_statuses(chunk.to_vec(), now).await?;
    }
    Ok(n)
}
