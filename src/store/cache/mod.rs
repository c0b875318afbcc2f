//! Sensors' latest state held in memory, so the reads control systems make
//! most — latest coefficients, compensation, a sensor's summary — are
//! answered without a database round trip.
//!
//! [`CachedStore`] wraps any engine and caches [`Store::sensor`]: the
//! sensor's summary with its latest calibration. What is cached is the
//! state stored; the status, which depends on the time of the read, is
//! computed again on every hit ([`Status::of`]). The rules that keep every
//! read seeing every acknowledged write:
//!
//! * **Writes through this process** ([`Store::insert_calibration`])
//!   settle the sensor's entry after the database answered and before the
//!   caller can answer its client: a calibration stored brings the cached
//!   summary up to date by the rule the engines apply to the sensor's row
//!   ([`SensorSummary::after`]); any other end — a failure, an unknown
//!   outcome (a failed commit may still have landed), a write racing
//!   another of the same sensor — drops it. So a station's next
//!   submission of that sensor finds it cached. A type assigned
//!   ([`Store::assign_sensor_type`]) drops the entry.
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

use std::sync::Arc;
use std::sync::Mutex;

use async_trait::async_trait;
use bytes::Bytes;
use uuid::Uuid;

use super::{
    CalibrationSummary, Claim, DoneKey, HistoryQuery, IdempotencyKey, NewCalibration, SensorQuery,
    SensorSummary, Series, Store, StoreError, Stored, StoredSubmission,
};
use crate::domain::sensor_types::SensorType;
use crate::domain::session::SessionRecord;
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

/// An engine with [`SensorCache`] in front of its sensor reads and
/// [`TokenCache`] in front of its token reads.
pub struct CachedStore {
    inner: Arc<dyn Store>,
    cache: Arc<SensorCache>,
    tokens: Arc<TokenCache>,
    /// Stopped at [`Store::close`] (the PostgreSQL listener).
    listener: Mutex<Option<tokio::task::JoinHandle<()>>>,
    /// The engine's check of its file (SQLite), if it has one.
    file: Option<FileCheck>,
}

/// The engine's own check that the database it serves is still there (the
/// SQLite pool's: the file at its path is the one it opened, a good check
/// standing for 50 ms). Cached answers run it first, so nothing is answered
/// from memory that the database no longer backs — a file removed, or a
/// backup moved over it (503, as the engine answers then).
pub type FileCheck = Arc<dyn Fn() -> Result<(), StoreError> + Send + Sync>;

impl CachedStore {
    /// `inner` behind `cache` and `tokens`; `listener` is the task that
    /// keeps both in step with other processes, if any.
    pub fn new(
        inner: Arc<dyn Store>,
        cache: Arc<SensorCache>,
        tokens: Arc<TokenCache>,
        listener: Option<tokio::task::JoinHandle<()>>,
    ) -> Self {
        CachedStore {
            inner,
            cache,
            tokens,
            listener: Mutex::new(listener),
            file: None,
        }
    }

    /// The same, for an engine whose file `check` checks.
    pub fn watching(mut self, check: FileCheck) -> Self {
        self.file = Some(check);
        self
    }

    /// The sensor cache (for tests and metrics).
    pub fn cache(&self) -> &Arc<SensorCache> {
        &self.cache
    }

    /// The token cache (for tests).
    pub fn tokens(&self) -> &Arc<TokenCache> {
        &self.tokens
    }

    /// 503 when the database file is not the one served (SQLite).
    fn follow_the_file(&self) -> Result<(), StoreError> {
        match &self.file {
            Some(check) => check(),
            None => Ok(()),
        }
    }
}

#[async_trait]
impl Store for CachedStore {
    async fn sensor(
        &self,
        sensor_id: String,
        now: Timestamp,
    ) -> Result<Option<SensorSummary>, StoreError> {
        self.follow_the_file()?;
        if let Some(hit) = self.cache.get(&sensor_id) {
            metrics::counter!("accelcal_sensor_cache_total", "outcome" => "hit").increment(1);
            return Ok(Some(at(&hit, now)));
        }
        metrics::counter!("accelcal_sensor_cache_total", "outcome" => "miss").increment(1);
        let epoch = self.cache.begin();
        let found = self.inner.sensor(sensor_id, now).await?;
        if let (Some(epoch), Some(s)) = (epoch, &found) {
            self.cache.fill(epoch, s);
        }
        Ok(found)
    }

    /// From the cached summary when there is one (no copy of it); else
    /// read, and cached, as [`Store::sensor`] does.
    async fn latest_calibration_id(&self, sensor_id: String) -> Result<Option<Uuid>, StoreError> {
        self.follow_the_file()?;
        if let Some(hit) = self.cache.get(&sensor_id) {
            metrics::counter!("accelcal_sensor_cache_total", "outcome" => "hit").increment(1);
            return Ok(Some(hit.latest.id));
        }
        Ok(self
            .sensor(sensor_id, Timestamp::now())
            .await?
            .map(|s| s.latest.id))
    }

    /// The latest calibration performed strictly before `before`. When the
    /// sensor is cached and its latest calibration (the greatest by
    /// `(performed_at, id)`) was performed before `before`, that one is the
    /// answer — nothing later exists to be "before" — and the database is not
    /// asked: the common case of a submission, which follows its sensor's
    /// summary read ([`Store::sensor`]) and comes after its latest. Otherwise
    /// the engine answers.
    async fn previous_calibration(
        &self,
        sensor_id: String,
        before: Timestamp,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        self.follow_the_file()?;
        if let Some(hit) = self.cache.get(&sensor_id)
            && hit.latest.performed_at < before
        {
            return Ok(Some(hit.latest.clone()));
        }
        self.inner.previous_calibration(sensor_id, before).await
    }

    async fn insert_calibration(
        &self,
        c: NewCalibration,
        key: Option<IdempotencyKey>,
    ) -> Result<Stored, StoreError> {
        self.follow_the_file()?;
        // A task of its own, so that the cache learns the write's end even
        // when the request is cancelled meanwhile (its client gone): the
        // write stands, and a read must not fill from before it.
        let (inner, cache) = (self.inner.clone(), self.cache.clone());
        tokio::spawn(async move {
            let write = cache.write(&c.sensor_id);
            let stored = (CalibrationSummary::from(&c), c.assigns_type);
            let out = inner.insert_calibration(c, key).await;
            write.settle(matches!(out, Ok(Stored::New)).then_some(stored));
            out
        })
        .await
        .map_err(|e| StoreError::Unavailable(Box::new(e)))?
    }

    async fn assign_sensor_type(
        &self,
        sensor_id: String,
        type_id: String,
    ) -> Result<bool, StoreError> {
        self.follow_the_file()?;
        let out = self
            .inner
            .assign_sensor_type(sensor_id.clone(), type_id)
            .await;
        self.cache.invalidate(&sensor_id);
        out
    }

    async fn close(&self) {
        let listener = self
            .listener
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        if let Some(l) = listener {
            l.abort();
        }
        self.cache.reset(false);
        self.tokens.reset(false);
        self.inner.close().await;
    }

    // Everything else is the engine's.

    async fn ping(&self) -> Result<(), StoreError> {
        self.inner.ping().await
    }
    async fn claim_key(
        &self,
        key: IdempotencyKey,
        now: Timestamp,
        lease_until: Timestamp,
    ) -> Result<Claim, StoreError> {
        self.inner.claim_key(key, now, lease_until).await
    }
    async fn release_key(&self, key: IdempotencyKey) -> Result<(), StoreError> {
        self.inner.release_key(key).await
    }
    async fn calibration_result(&self, id: Uuid) -> Result<Option<Bytes>, StoreError> {
        self.inner.calibration_result(id).await
    }
    async fn submission(&self, id: Uuid) -> Result<Option<StoredSubmission>, StoreError> {
        self.inner.submission(id).await
    }
    async fn calibration_summary(
        &self,
        id: Uuid,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        self.inner.calibration_summary(id).await
    }
    async fn sensors(&self, q: SensorQuery) -> Result<Vec<SensorSummary>, StoreError> {
        self.inner.sensors(q).await
    }
    async fn history(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<CalibrationSummary>, StoreError> {
        self.inner.history(sensor_id, q).await
    }
    async fn history_ids(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<Uuid>, StoreError> {
        self.inner.history_ids(sensor_id, q).await
    }
    async fn series(
        &self,
        sensor_id: String,
        from: Option<Timestamp>,
        to: Option<Timestamp>,
        limit: usize,
    ) -> Result<Series, StoreError> {
        self.inner.series(sensor_id, from, to, limit).await
    }
    async fn put_sensor_type(&self, t: SensorType) -> Result<bool, StoreError> {
        self.inner.put_sensor_type(t).await
    }
    async fn sensor_type(&self, type_id: String) -> Result<Option<SensorType>, StoreError> {
        self.inner.sensor_type(type_id).await
    }
    async fn sensor_types(&self) -> Result<Vec<SensorType>, StoreError> {
        self.inner.sensor_types().await
    }
    async fn insert_token(&self, t: TokenRecord) -> Result<(), StoreError> {
        self.inner.insert_token(t).await
    }
    async fn token(&self, id: Uuid) -> Result<Option<TokenRecord>, StoreError> {
        self.follow_the_file()?;
        if let Some(hit) = self.tokens.get(id) {
            return Ok(Some(hit));
        }
        let epoch = self.tokens.begin();
        let found = self.inner.token(id).await?;
        if let (Some(epoch), Some(t)) = (epoch, &found) {
            self.tokens.fill(epoch, t);
        }
        Ok(found)
    }
    async fn tokens(&self) -> Result<Vec<TokenRecord>, StoreError> {
        self.inner.tokens().await
    }
    /// Drops the token from the cache once the engine answered, whatever
    /// it answered, in a task of its own so that a cancelled request cannot
    /// skip the drop.
    async fn revoke_token(&self, id: Uuid, at: Timestamp) -> Result<bool, StoreError> {
        self.follow_the_file()?;
        let (inner, tokens) = (self.inner.clone(), self.tokens.clone());
        tokio::spawn(async move {
            let out = inner.revoke_token(id, at).await;
            tokens.invalidate(id);
            out
        })
        .await
        .map_err(|e| StoreError::Unavailable(Box::new(e)))?
    }
    async fn has_admin_token(&self) -> Result<bool, StoreError> {
        self.inner.has_admin_token().await
    }
    async fn insert_session(&self, s: SessionRecord) -> Result<(), StoreError> {
        self.inner.insert_session(s).await
    }
    async fn session(&self, id_hash: [u8; 32]) -> Result<Option<SessionRecord>, StoreError> {
        self.inner.session(id_hash).await
    }
    async fn delete_session(&self, id_hash: [u8; 32]) -> Result<bool, StoreError> {
        self.inner.delete_session(id_hash).await
    }
    async fn is_empty(&self) -> Result<bool, StoreError> {
        self.inner.is_empty().await
    }
    async fn export_calibrations(
        &self,
        after: Option<Uuid>,
        limit: usize,
    ) -> Result<Vec<NewCalibration>, StoreError> {
        self.inner.export_calibrations(after, limit).await
    }
    async fn done_keys(&self, since: Timestamp) -> Result<Vec<DoneKey>, StoreError> {
        self.inner.done_keys(since).await
    }
    async fn import_in_progress(&self) -> Result<Option<String>, StoreError> {
        self.inner.import_in_progress().await
    }
    async fn set_import_in_progress(&self, import: Option<String>) -> Result<(), StoreError> {
        self.inner.set_import_in_progress(import).await
    }
    async fn put_done_key(&self, k: DoneKey) -> Result<(), StoreError> {
        self.inner.put_done_key(k).await
    }
    async fn backup(&self) -> Result<Option<tempfile::NamedTempFile>, StoreError> {
        self.follow_the_file()?;
        self.inner.backup().await
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
