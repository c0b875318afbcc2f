//! Sensors' latest state held in memory, so the reads control systems make
//! most — latest coefficients, compensation, a sensor's summary — are
//! answered without a database round trip.
//!
//! Each engine holds a [`Cache`] and asks it first in the few operations it
//! serves — a sensor's summary with its latest calibration
//! ([`Sensors::sensor`](super::Sensors::sensor)), a token
//! ([`Tokens::token`](super::Tokens::token)) — and tells it of every write
//! of them; a [`Cache::off`] keeps nothing (the engines bare, in tests). What is cached is the
//! state stored; the status, which depends on the time of the read, is
//! computed again on every hit ([`Status::of`]). The rules that keep every
//! read seeing every acknowledged write:
//!
//! * **Writes through this process** ([`Calibrations::insert_calibration`](super::Calibrations::insert_calibration))
//!   settle the sensor's entry after the database answered and before the
//!   caller can answer its client: a calibration stored puts in the
//!   sensor's row as the database's upsert answered it
//!   ([`SensorRow`]) unless a later state of it is held (writes of one
//!   sensor in flight at once settle in any order; its calibration count
//!   orders their rows); any other end — a failure, an unknown outcome (a
//!   failed commit may still have landed) — drops it. So a station's next
//!   submission of that sensor finds it cached, and so does every
//!   submission to a sensor that many requests write at once. A type assigned
//!   ([`Sensors::assign_sensor_type`](super::Sensors::assign_sensor_type)) drops the entry.
//! * **A read racing a write** cannot put back what the write replaced:
//!   every change ticks a clock and stamps the sensor's stripe, and a read
//!   fills the cache only if its stripe was not stamped between its start
//!   and its end and no write of it is in flight ([`sensors`] has the
//!   rules).
//! * **Writes through other processes** (replicas sharing PostgreSQL) reach
//!   this one as notifications: a trigger announces every change of a
//!   sensor's row on commit (`pg_notify`), and a listener
//!   ([`super::postgres::listen`]) drops the entry when it hears it —
//!   except the echoes of this replica's own batches, which the previous
//!   rule already applied. The
//!   cache is used only while that listener is connected; it is emptied when
//!   the listener connects and bypassed while it is not, so a lost
//!   notification cannot leave an entry stale. A replica reading just after
//!   another replica's commit sees it once the notification has arrived
//!   (a few milliseconds on one host: the replica tests print it);
//!   in between it may answer the previous calibration — the same as a read
//!   that arrived a moment earlier — and a write of its own of that sensor
//!   in that moment may count on a summary without the other replica's
//!   calibration, until the notification drops it. SQLite has one serving
//!   process, so there the first two rules are the whole story.
//! * **Bounded**: at most [`CAPACITY`] sensors; when full, an arbitrary
//!   entry makes room.
//!
//! Issued tokens are cached beside the sensors, by the rules of [`tokens`].
//!
//! Kept because it pays: with both engines served directly, at 64
//! connections and with issued tokens, coefficients reads fell to 0.43×
//! (SQLite) and 0.21× (PostgreSQL) of their rate, history to 0.57× and
//! 0.45×, submissions to 0.65× and 0.54× (`benches/load.rs`, side by side).
//! The hand-written part is the consistency protocol above, which no cache
//! crate provides; the map under it is a `HashMap`.

use std::future::Future;
use std::sync::Arc;
use std::sync::Mutex;

use uuid::Uuid;

use super::{CalibrationSummary, SensorRow, SensorSummary, StoreError, Stored};
use crate::domain::review::Basis;
use crate::domain::status::Status;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use accelcal_core::decision::Verdict;

pub mod sensors;
pub mod tokens;

pub use sensors::{CAPACITY, STRIPES, SensorCache, Write};
pub use tokens::TokenCache;

/// A cached summary as of `now`: its status computed again.
fn at(summary: &SensorSummary, now: Timestamp) -> SensorSummary {
    let mut s = summary.clone();
    s.status = Status::of(s.latest_verdict == Some(Verdict::Fail), s.due_at, now);
    s
}

/// What an engine keeps in memory: its sensors ([`SensorCache`]) and its
/// tokens ([`TokenCache`]), and the task that keeps both in step with other
/// processes, if any (PostgreSQL's listener).
#[derive(Debug)]
pub struct Cache {
    sensors: Arc<SensorCache>,
    tokens: Arc<TokenCache>,
    /// Stopped at [`Cache::close`].
    listener: Mutex<Option<tokio::task::JoinHandle<()>>>,
}

impl Cache {
    /// A cache usable at once (`live`), or only once a listener makes it
    /// so.
    pub fn new(live: bool) -> Self {
        Cache {
            sensors: Arc::new(SensorCache::new(CAPACITY, live)),
            tokens: Arc::new(TokenCache::new(tokens::CAPACITY, live)),
            listener: Mutex::new(None),
        }
    }

    /// A cache that keeps nothing: every read asks the database.
    pub fn off() -> Self {
        Self::new(false)
    }

    /// The same, stopping `listener` when it closes.
    pub fn listening(self, listener: tokio::task::JoinHandle<()>) -> Self {
        *self.listener.lock().unwrap_or_else(|e| e.into_inner()) = Some(listener);
        self
    }

    /// The sensor cache (for the listener, tests and metrics).
    pub fn sensors(&self) -> &Arc<SensorCache> {
        &self.sensors
    }

    /// The token cache (for the listener and tests).
    pub fn tokens(&self) -> &Arc<TokenCache> {
        &self.tokens
    }

    /// A sensor's summary as of `now`: the cached one, or what `read` finds
    /// (kept when the rules of [`sensors`] allow).
    pub async fn sensor(
        &self,
        sensor_id: &str,
        now: Timestamp,
        read: impl Future<Output = Result<Option<SensorSummary>, StoreError>>,
    ) -> Result<Option<SensorSummary>, StoreError> {
        if let Some(hit) = self.sensors.get(sensor_id) {
            metrics::counter!("accelcal_sensor_cache_total", "outcome" => "hit").increment(1);
            return Ok(Some(at(&hit, now)));
        }
        metrics::counter!("accelcal_sensor_cache_total", "outcome" => "miss").increment(1);
        let epoch = self.sensors.begin();
        let found = read.await?;
        if let (Some(epoch), Some(s)) = (epoch, &found) {
            self.sensors.fill(epoch, s);
        }
        Ok(found)
    }

    /// The id of a cached sensor's latest calibration (no copy of the
    /// summary); `None` when it is not cached.
    pub fn latest_calibration_id(
        &self,
        sensor_id: &str,
    ) -> Option<(Uuid, crate::domain::review::State)> {
        let hit = self.sensors.get(sensor_id)?;
        metrics::counter!("accelcal_sensor_cache_total", "outcome" => "hit").increment(1);
        Some((hit.latest.id, hit.latest.state))
    }

    /// The latest calibration performed strictly before `before`, when the
    /// cache can tell: the sensor is cached and its summary answers
    /// ([`crate::store::SensorSummary::previous_before`]). `None` means: ask
    /// the database.
    pub fn previous_calibration(
        &self,
        sensor_id: &str,
        before: Timestamp,
    ) -> Option<CalibrationSummary> {
        let hit = self.sensors.get(sensor_id)?;
        hit.previous_before(before, Basis::NotRejected).cloned()
    }

    /// Runs `write`, which stores `c` and answers the sensor's row as it
    /// left it, in a task of its own, so that the cache learns the write's
    /// end even when the request is cancelled meanwhile (its client gone):
    /// the write stands, and a read must not fill from before it. The
    /// sensor's entry is replaced or dropped ([`Write::settle`]).
    pub async fn insert_calibration(
        &self,
        c: CalibrationSummary,
        write: impl Future<Output = Result<(Stored, Option<SensorRow>), StoreError>> + Send + 'static,
    ) -> Result<Stored, StoreError> {
        let cache = self.sensors.clone();
        tokio::spawn(async move {
            let writing = cache.write(&c.sensor_id);
            match write.await {
                Ok((Stored::New, Some(row))) => {
                    writing.settle(Some((c, row)));
                    Ok(Stored::New)
                }
                Ok((stored, _)) => {
                    writing.settle(None);
                    Ok(stored)
                }
                Err(e) => {
                    writing.settle(None);
                    Err(e)
                }
            }
        })
        .await
        .map_err(|e| StoreError::Unavailable(Box::new(e)))?
    }

    /// Drops what is cached of a sensor whose row changed (its type).
    pub fn sensor_changed(&self, sensor_id: &str) {
        self.sensors.invalidate(sensor_id);
    }

    /// Runs `write`, which changes what is stored of `sensors` other than
    /// by a new calibration alone (a review: a latest's state, or which is
    /// latest), in a task of its own: reads do not fill their entries while
    /// it runs, and the entries are dropped at its end, whatever it
    /// answered — so that no read from before the write stays cached.
    pub async fn changing<T: Send + 'static>(
        &self,
        sensors: &[String],
        write: impl Future<Output = Result<T, StoreError>> + Send + 'static,
    ) -> Result<T, StoreError> {
        let cache = self.sensors.clone();
        let sensors = sensors.to_vec();
        tokio::spawn(async move {
            let writing: Vec<_> = sensors.iter().map(|s| cache.write(s)).collect();
            let out = write.await;
            for w in writing {
                w.settle(None);
            }
            out
        })
        .await
        .map_err(|e| StoreError::Unavailable(Box::new(e)))?
    }

    /// A token: the cached record, or what `read` finds (kept when the
    /// rules of [`tokens`] allow).
    pub async fn token(
        &self,
        id: Uuid,
        read: impl Future<Output = Result<Option<TokenRecord>, StoreError>>,
    ) -> Result<Option<TokenRecord>, StoreError> {
        if let Some(hit) = self.tokens.get(id) {
            return Ok(Some(hit));
        }
        let epoch = self.tokens.begin();
        let found = read.await?;
        if let (Some(epoch), Some(t)) = (epoch, &found) {
            self.tokens.fill(epoch, t);
        }
        Ok(found)
    }

    /// Runs `revoke` and drops the token once the engine answered, whatever
    /// it answered, in a task of its own so that a cancelled request cannot
    /// skip the drop.
    pub async fn revoke_token(
        &self,
        id: Uuid,
        revoke: impl Future<Output = Result<bool, StoreError>> + Send + 'static,
    ) -> Result<bool, StoreError> {
        let tokens = self.tokens.clone();
        tokio::spawn(async move {
            let out = revoke.await;
            tokens.invalidate(id);
            out
        })
        .await
        .map_err(|e| StoreError::Unavailable(Box::new(e)))?
    }

    /// Stops the listener and empties both caches, for good.
    pub fn close(&self) {
        let listener = self
            .listener
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        if let Some(l) = listener {
            l.abort();
        }
        self.sensors.reset(false);
        self.tokens.reset(false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ts(s: &str) -> Timestamp {
        Timestamp::parse(s).unwrap()
    }

    fn summary(sensor: &str, due: Option<&str>, verdict: Option<Verdict>) -> SensorSummary {
        let plain = SensorSummary::for_test(sensor);
        SensorSummary {
            latest_verdict: verdict,
            due_at: due.map(ts),
            latest: CalibrationSummary {
                verdict,
                due_at: due.map(ts),
                ..plain.latest.clone()
            },
            ..plain
        }
    }

    /// The status is the domain rule at the time of the read, not at the
    /// time of the fill: one cached entry, four reads.
    #[test]
    fn a_hit_computes_the_status_at_the_read() {
        let due = summary("S", Some("2026-06-01T00:00:00Z"), Some(Verdict::Pass));
        let at_ = |now: &str| at(&due, ts(now)).status;
        assert_eq!(at_("2026-01-01T00:00:00Z"), Status::Ok);
        assert_eq!(at_("2026-05-15T00:00:00Z"), Status::DueSoon);
        assert_eq!(at_("2026-06-01T00:00:01Z"), Status::Overdue);
        let failed = summary("S", Some("2026-06-01T00:00:00Z"), Some(Verdict::Fail));
        assert_eq!(
            at(&failed, ts("2026-01-01T00:00:00Z")).status,
            Status::Failed
        );
        let conditional = summary("S", None, Some(Verdict::Conditional));
        assert_eq!(
            at(&conditional, ts("2026-01-01T00:00:00Z")).status,
            Status::Unknown
        );
    }
}
