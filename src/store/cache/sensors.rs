//! The cached sensors and the clock that says when a read or a write may
//! put what it found into the cache.
//!
//! Every change the cache hears of — a drop (a notification from another
//! replica, a type assigned here, a write whose outcome is unknown), the
//! end of a write through this process, a reset — ticks one clock
//! (`epoch`) and stamps the changed sensor's stripe (one of [`STRIPES`],
//! by a hash of its id) with the new tick. Then:
//!
//! * a **read** that began at tick `e` fills its sensor only if the stripe
//!   was not stamped after `e`, no reset happened after `e`, and no write
//!   of the stripe is in flight (its result might or might not include the
//!   write);
//! * a **write** through this process ([`SensorCache::write`]) that
//!   stored calibration `c` puts in the sensor's row as the database's
//!   upsert answered it ([`SensorRow`]), with its latest calibration —
//!   `c`, or the cached summary's latest — only if it was the only write
//!   of its stripe in flight from start to end and the stripe was not
//!   stamped meanwhile; in every other case — failed, unknown outcome, a
//!   latest that is neither, a concurrent write, a drop — the entry is
//!   dropped and the next read fills it from the database.
//!
//! Sensors sharing a stripe hold each other back, which costs a read, never
//! a stale answer.

use std::collections::HashMap;
use std::hash::{BuildHasher, RandomState};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use crate::store::{CalibrationSummary, SensorRow, SensorSummary};

/// Sensors cached at most (a summary is about 1 KiB).
pub const CAPACITY: usize = 4096;

/// How many stripes the sensors' ids hash into (12 bytes each): 64 sensors
/// written at once share a stripe with one of the others with a chance of
/// 1 − (1 − 1/4096)⁶³ ≈ 1.5 %.
pub const STRIPES: usize = 4096;

/// The cached summaries and what guards them.
#[derive(Debug)]
pub struct SensorCache {
    inner: Mutex<Entries>,
    /// Whether the cache may be used: always for an engine no other process
    /// writes to; for PostgreSQL, while the listener is connected.
    live: AtomicBool,
    capacity: usize,
    hasher: RandomState,
}

#[derive(Debug)]
struct Entries {
    map: HashMap<String, Arc<SensorSummary>>,
    /// The clock: ticked by every change.
    epoch: u64,
    /// The tick of the last reset.
    reset_at: u64,
    /// Per stripe, the tick of its last change.
    changed_at: Box<[u64; STRIPES]>,
    /// Per stripe, writes through this process in flight.
    writing: Box<[u32; STRIPES]>,
}

impl Entries {
    /// Ticks the clock and stamps `stripe` with the new tick.
    fn stamp(&mut self, stripe: usize) -> u64 {
        self.epoch += 1;
        self.changed_at[stripe] = self.epoch;
        self.epoch
    }

    /// Whether nothing of `stripe` changed, and nothing was reset, after `epoch`.
    fn unchanged_since(&self, stripe: usize, epoch: u64) -> bool {
        self.reset_at <= epoch && self.changed_at[stripe] <= epoch
    }
}

impl SensorCache {
    /// An empty cache of at most `capacity` sensors, live or not.
    pub fn new(capacity: usize, live: bool) -> Self {
        SensorCache {
            inner: Mutex::new(Entries {
                map: HashMap::new(),
                epoch: 0,
                reset_at: 0,
                changed_at: Box::new([0; STRIPES]),
                writing: Box::new([0; STRIPES]),
            }),
            live: AtomicBool::new(live),
            capacity,
            hasher: RandomState::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Entries> {
        // The lock guards plain data; a panic elsewhere cannot leave it
        // half-updated in a way that matters, so a poisoned lock is used.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn stripe(&self, sensor_id: &str) -> usize {
        (self.hasher.hash_one(sensor_id) % STRIPES as u64) as usize
    }

    /// Drops what is cached of `sensor_id`.
    pub fn invalidate(&self, sensor_id: &str) {
        let stripe = self.stripe(sensor_id);
        let mut e = self.lock();
        e.stamp(stripe);
        e.map.remove(sensor_id);
    }

    /// Empties the cache and makes it usable (or not) from now on: what
    /// was cached while notifications could be missed is gone.
    pub fn reset(&self, live: bool) {
        let mut e = self.lock();
        e.epoch += 1;
        e.reset_at = e.epoch;
        e.map.clear();
        self.live.store(live, Ordering::SeqCst);
    }

    /// The tick a read starts at, or `None` when the cache is not live.
    pub(super) fn begin(&self) -> Option<u64> {
        let e = self.lock();
        self.live.load(Ordering::SeqCst).then_some(e.epoch)
    }

    pub(super) fn get(&self, sensor_id: &str) -> Option<Arc<SensorSummary>> {
        if !self.live.load(Ordering::SeqCst) {
            return None;
        }
        self.lock().map.get(sensor_id).cloned()
    }

    /// Keeps what a read that began at `epoch` found, unless its sensor
    /// changed since or is being written.
    pub(super) fn fill(&self, epoch: u64, summary: &SensorSummary) {
        let stripe = self.stripe(&summary.sensor_id);
        let mut e = self.lock();
        if !e.unchanged_since(stripe, epoch)
            || e.writing[stripe] > 0
            || !self.live.load(Ordering::SeqCst)
        {
            return;
        }
        self.put(&mut e, Arc::new(summary.clone()));
    }

    /// Inserts `summary`, making room if the cache is full.
    fn put(&self, e: &mut Entries, summary: Arc<SensorSummary>) {
        if e.map.len() >= self.capacity
            && !e.map.contains_key(&summary.sensor_id)
            && let Some(victim) = e.map.keys().next().cloned()
        {
            e.map.remove(&victim);
        }
        e.map.insert(summary.sensor_id.clone(), summary);
    }

    /// A write of `sensor_id` through this process begins: until it is
    /// [settled](Write::settle) (or dropped), reads of its stripe do not
    /// fill.
    pub fn write(&self, sensor_id: &str) -> Write<'_> {
        let stripe = self.stripe(sensor_id);
        let mut e = self.lock();
        e.writing[stripe] += 1;
        Write {
            cache: self,
            sensor_id: sensor_id.to_owned(),
            stripe,
            epoch: e.epoch,
            settled: false,
        }
    }

    /// Ends a write; see [`Write::settle`].
    fn end(&self, w: &Write<'_>, stored: Option<(CalibrationSummary, SensorRow)>) {
        let kept = self.apply(w, stored);
        let outcome = if kept { "kept" } else { "dropped" };
        metrics::counter!("accelcal_sensor_cache_writes_total", "outcome" => outcome).increment(1);
    }

    /// [`end`](Self::end)'s work under the lock; whether the entry was
    /// kept up to date.
    fn apply(&self, w: &Write<'_>, stored: Option<(CalibrationSummary, SensorRow)>) -> bool {
        let mut e = self.lock();
        let alone = e.writing[w.stripe] == 1;
        e.writing[w.stripe] -= 1;
        let unchanged = e.unchanged_since(w.stripe, w.epoch);
        e.stamp(w.stripe);
        let cached = e.map.remove(&w.sensor_id);
        let certain = alone && unchanged && self.live.load(Ordering::SeqCst);
        let Some((c, row)) = stored.filter(|_| certain) else {
            return false;
        };
        let candidates = std::iter::once(&c).chain(cached.as_deref().map(|s| &s.latest));
        match row.summary(candidates) {
            Some(s) => {
                self.put(&mut e, Arc::new(s));
                true
            }
            None => false,
        }
    }

    /// Whether reads may use the cache now.
    pub fn is_live(&self) -> bool {
        self.live.load(Ordering::SeqCst)
    }

    /// Sensors cached now.
    pub fn len(&self) -> usize {
        self.lock().map.len()
    }

    /// Whether nothing is cached.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether `sensor_id` is cached now.
    pub fn contains(&self, sensor_id: &str) -> bool {
        self.lock().map.contains_key(sensor_id)
    }
}

/// A write of one sensor through this process, in flight.
#[derive(Debug)]
#[must_use = "a write holds back its stripe's fills until it is settled or dropped"]
pub struct Write<'a> {
    cache: &'a SensorCache,
    sensor_id: String,
    stripe: usize,
    /// The tick at its start.
    epoch: u64,
    settled: bool,
}

impl Write<'_> {
    /// Ends the write. `stored` is the calibration it stored and the
    /// sensor's row as the database answered the write, or `None` when
    /// nothing was stored or the outcome is unknown. The cached summary
    /// is replaced with it where the module's rule allows, dropped
    /// otherwise.
    pub fn settle(mut self, stored: Option<(CalibrationSummary, SensorRow)>) {
        self.settled = true;
        self.cache.end(&self, stored);
    }
}

impl Drop for Write<'_> {
    /// A write abandoned before it was settled (its request cancelled):
    /// its outcome is unknown, so its sensor is dropped.
    fn drop(&mut self) {
        if !self.settled {
            self.cache.end(self, None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::timestamp::Timestamp;
    use uuid::Uuid;

    pub(crate) fn ts(s: &str) -> Timestamp {
        Timestamp::parse(s).unwrap()
    }

    fn summary(sensor: &str) -> SensorSummary {
        SensorSummary::for_test(sensor)
    }

    /// A calibration of `sensor` performed on `day` of January 2026.
    fn newer(sensor: &str, id: u128, day: u8) -> CalibrationSummary {
        CalibrationSummary {
            performed_at: ts(&format!("2026-01-{day:02}T00:00:00Z")),
            ..CalibrationSummary::for_test(id, sensor, 0.5, 1.0)
        }
    }

    /// What the database answers when `c` is stored after
    /// [`summary`]`(sensor)`'s one calibration (id 7, performed in 2025).
    fn row(c: &CalibrationSummary) -> SensorRow {
        let before = summary(&c.sensor_id);
        let newest = (c.performed_at, c.id) > (before.latest.performed_at, before.latest.id);
        let latest = if newest { c } else { &before.latest };
        SensorRow {
            sensor_id: c.sensor_id.clone(),
            calibration_count: 2,
            first_performed_at: before.first_performed_at.min(c.performed_at),
            latest_performed_at: latest.performed_at,
            latest_calibration_id: latest.id,
            sensor_type: None,
            latest_verdict: latest.verdict,
            due_at: latest.due_at,
        }
    }

    fn stored(sensor: &str, id: u128, day: u8) -> Option<(CalibrationSummary, SensorRow)> {
        let c = newer(sensor, id, day);
        let r = row(&c);
        Some((c, r))
    }

    fn filled(c: &SensorCache, sensor: &str) {
        c.fill(c.begin().unwrap(), &summary(sensor));
        assert!(c.contains(sensor));
    }

    #[test]
    fn a_read_that_raced_a_drop_does_not_fill() {
        let c = SensorCache::new(8, true);
        let epoch = c.begin().unwrap();
        c.invalidate("S");
        c.fill(epoch, &summary("S"));
        assert!(c.get("S").is_none(), "a fill from before the drop was kept");
        filled(&c, "S");
        c.invalidate("S");
        assert!(c.get("S").is_none());
    }

    /// Stripes: a drop of one sensor holds back another sensor's read only
    /// when the two share a stripe.
    #[test]
    fn a_drop_holds_back_reads_of_its_stripe_only() {
        let c = SensorCache::new(1024, true);
        let apart = (0..)
            .map(|i| format!("T{i}"))
            .find(|t| c.stripe(t) != c.stripe("S"))
            .unwrap();
        let together = (0..)
            .map(|i| format!("U{i}"))
            .find(|u| c.stripe(u) == c.stripe("S"))
            .unwrap();
        let epoch = c.begin().unwrap();
        c.invalidate("S");
        c.fill(epoch, &summary(&apart));
        assert!(
            c.contains(&apart),
            "a drop of another stripe held a fill back"
        );
        c.fill(epoch, &summary(&together));
        assert!(!c.contains(&together), "a fill raced a drop of its stripe");
    }

    #[test]
    fn a_cache_that_is_not_live_neither_answers_nor_fills() {
        let c = SensorCache::new(8, true);
        filled(&c, "S");
        c.reset(false);
        assert!(c.is_empty(), "reset empties");
        assert!(c.begin().is_none());
        assert!(c.get("S").is_none());
        c.reset(true);
        let epoch = c.begin().unwrap();
        c.reset(false);
        c.fill(epoch, &summary("S"));
        assert!(c.is_empty());
        // Nor does a write bring an entry back.
        c.reset(true);
        filled(&c, "S");
        let w = c.write("S");
        c.reset(false);
        w.settle(stored("S", 8, 2));
        assert!(c.is_empty());
    }

    #[test]
    fn the_cache_holds_at_most_its_capacity() {
        let c = SensorCache::new(3, true);
        for i in 0..10 {
            c.fill(c.begin().unwrap(), &summary(&format!("S{i}")));
            assert!(c.len() <= 3);
        }
        assert_eq!(c.len(), 3);
        assert!(c.get("S9").is_some(), "the newest entry is kept");
        // Refilling a present sensor evicts nothing.
        c.fill(c.begin().unwrap(), &summary("S9"));
        assert_eq!(c.len(), 3);
    }

    /// A write alone puts in the row the database answered, with the
    /// calibration it names as latest: the one written, or the one cached.
    #[test]
    fn a_write_alone_updates_its_sensor() {
        let c = SensorCache::new(8, true);
        filled(&c, "S");
        let w = c.write("S");
        let (written, r) = stored("S", 8, 2).unwrap();
        w.settle(Some((written.clone(), r.clone())));
        let s = c.get("S").expect("the written sensor stays cached");
        assert_eq!(s.latest, written);
        assert_eq!(s.calibration_count, 2);
        assert_eq!(s.latest_performed_at, written.performed_at);

        // An older calibration: the cached latest stays the latest.
        let older = CalibrationSummary {
            performed_at: ts("2020-01-01T00:00:00Z"),
            ..newer("S", 9, 1)
        };
        let mut r = row(&older);
        r.latest_calibration_id = written.id;
        r.latest_performed_at = written.performed_at;
        c.write("S").settle(Some((older.clone(), r)));
        let s = c.get("S").expect("still cached");
        assert_eq!(
            (s.latest.id, s.first_performed_at),
            (written.id, older.performed_at)
        );

        // A sensor not cached is put in when the write is its latest.
        let (fresh, r) = stored("T", 10, 3).unwrap();
        c.write("T").settle(Some((fresh.clone(), r)));
        assert_eq!(c.get("T").unwrap().latest, fresh);
    }

    /// Every other end of a write drops the entry.
    #[test]
    fn a_write_that_is_not_alone_or_did_not_store_drops_its_sensor() {
        let c = SensorCache::new(8, true);
        let stored = || stored("S", 8, 2);
        // Nothing stored, or the outcome unknown.
        filled(&c, "S");
        c.write("S").settle(None);
        assert!(!c.contains("S"));
        // Abandoned.
        filled(&c, "S");
        drop(c.write("S"));
        assert!(!c.contains("S"));
        // A latest that is neither the write's nor the cached one (a
        // newer calibration stored meanwhile by another process).
        filled(&c, "S");
        let (written, mut r) = stored().unwrap();
        r.latest_calibration_id = Uuid::from_u128(99);
        c.write("S").settle(Some((written, r)));
        assert!(!c.contains("S"));
        // Dropped meanwhile (another replica's notification).
        filled(&c, "S");
        let w = c.write("S");
        c.invalidate("S");
        c.fill(c.begin().unwrap(), &summary("S"));
        w.settle(stored());
        assert!(!c.contains("S"), "a write updated an entry after a drop");
        // Two writes of the sensor in flight: neither knows the other's
        // effect, whichever ends first.
        for first_ends_first in [true, false] {
            filled(&c, "S");
            let (a, b) = (c.write("S"), c.write("S"));
            let (first, second) = if first_ends_first { (a, b) } else { (b, a) };
            first.settle(stored());
            assert!(!c.contains("S"));
            c.fill(c.begin().unwrap(), &summary("S"));
            assert!(
                !c.contains("S"),
                "a read filled while a write was in flight"
            );
            second.settle(stored());
            assert!(!c.contains("S"));
        }
    }

    /// A read that may have seen the write's effect cannot fill while the
    /// write is in flight, nor replace the write's row after it ended if it
    /// began before.
    #[test]
    fn a_read_racing_a_write_does_not_fill() {
        let c = SensorCache::new(8, true);
        let w = c.write("S");
        let epoch = c.begin().unwrap();
        c.fill(epoch, &summary("S"));
        assert!(!c.contains("S"), "filled during a write");
        w.settle(stored("S", 8, 2));
        assert_eq!(
            c.get("S").unwrap().latest.id.as_u128(),
            8,
            "the write's row"
        );
        c.fill(epoch, &summary("S"));
        assert_eq!(
            c.get("S").unwrap().latest.id.as_u128(),
            8,
            "filled from before the write's end"
        );
    }
}
