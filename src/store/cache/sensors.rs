//! The cached sensors and the clock that says when a read or a write may
//! put what it found into the cache.
//!
//! Every change the cache hears of — a drop (a notification from another
//! replica, a type assigned here, a write whose outcome is unknown, an
//! entry evicted), the end of a write through this process, a reset —
//! ticks one clock (`epoch`) and stamps the changed sensor's stripe (one of
//! [`STRIPES`], by a hash of its id) with the new tick; a drop also marks
//! the stripe dropped at that tick. Then:
//!
//! * a **read** that began at tick `e` fills its sensor only if the stripe
//!   was not stamped after `e`, no reset happened after `e`, and no write
//!   of the stripe is in flight (its result might or might not include the
//!   write);
//! * a **write** through this process ([`SensorCache::write`]) that
//!   stored calibration `c` puts in the sensor's row as the database's
//!   upsert answered it ([`SensorRow`]), with its latest calibration —
//!   `c`, or the cached summary's latest — if the stripe was not dropped
//!   and nothing was reset since the write began, and no entry of a
//!   **later state** is held. Between two drops of a sensor only
//!   calibrations are added to it (anything else that changes its row —
//!   a review, a type, another replica's act — is a drop), so its
//!   `calibration_count` numbers its states: of two writes in flight at
//!   once, whichever settles last, the entry is the row with the greater
//!   count, and rows of equal count are one state. A write whose row names
//!   a latest it does not know (another write's, in the same batch or
//!   settled later) cannot put it; it leaves a floor ([`Held::AtLeast`])
//!   that keeps every write of an earlier state from putting its row, and
//!   that a write of the same state which does know the latest replaces.
//!   Any other end — failed, unknown outcome, abandoned, or begun before
//!   a drop (its row may be of the state before the drop's change, whose
//!   count does not compare) — drops the entry. So after a drop the writes
//!   in flight at it drop it in turn, and a sensor written without pause
//!   stays uncached until its writes pause: never stale, only read from
//!   the database, as every sensor written by requests at once was before.
//!
//! Sensors sharing a stripe hold each other back, which costs a read, never
//! a stale answer. One hot sensor written by many requests at once stays
//! cached: its writes keep it current (BENCHMARKS.md, "A hot sensor kept
//! by its writes").

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

/// What the cache holds of a sensor.
#[derive(Debug, Clone)]
enum Held {
    /// Its summary, as the database last stood as far as this process knows.
    Known(Arc<SensorSummary>),
    /// A write stored its sensor's state with this `calibration_count`
    /// without knowing that state's latest calibration: a miss for reads,
    /// and a floor for writes (module docs).
    AtLeast(u64),
}

impl Held {
    /// The `calibration_count` of the state held.
    fn count(&self) -> u64 {
        match self {
            Held::Known(s) => s.calibration_count,
            Held::AtLeast(n) => *n,
        }
    }

    fn known(&self) -> Option<&Arc<SensorSummary>> {
        match self {
            Held::Known(s) => Some(s),
            Held::AtLeast(_) => None,
        }
    }
}

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
    map: HashMap<String, Held>,
    /// The clock: ticked by every change.
    epoch: u64,
    /// The tick of the last reset.
    reset_at: u64,
    /// Per stripe, the tick of its last change.
    changed_at: Box<[u64; STRIPES]>,
    /// Per stripe, the tick of its last drop.
    dropped_at: Box<[u64; STRIPES]>,
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

    /// Stamps `stripe` as dropped: no write of it in flight puts its row.
    fn drop_stripe(&mut self, stripe: usize) {
        let tick = self.stamp(stripe);
        self.dropped_at[stripe] = tick;
    }

    /// Whether `stripe` was neither dropped nor reset after `epoch`.
    fn undropped_since(&self, stripe: usize, epoch: u64) -> bool {
        self.reset_at <= epoch && self.dropped_at[stripe] <= epoch
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
                dropped_at: Box::new([0; STRIPES]),
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
        e.drop_stripe(stripe);
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
        self.lock().map.get(sensor_id)?.known().cloned()
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
        self.put(
            &mut e,
            &summary.sensor_id,
            Held::Known(Arc::new(summary.clone())),
        );
    }

    /// Holds `held` for `sensor_id`, making room if the cache is full: the
    /// sensor evicted is dropped, so that no write in flight of it puts an
    /// older state in after the floor it may have held.
    fn put(&self, e: &mut Entries, sensor_id: &str, held: Held) {
        if e.map.len() >= self.capacity
            && !e.map.contains_key(sensor_id)
            && let Some(victim) = e.map.keys().next().cloned()
        {
            e.map.remove(&victim);
            let stripe = self.stripe(&victim);
            e.drop_stripe(stripe);
        }
        e.map.insert(sensor_id.to_owned(), held);
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

    /// [`end`](Self::end)'s work under the lock; whether the sensor's
    /// summary is cached after it.
    fn apply(&self, w: &Write<'_>, stored: Option<(CalibrationSummary, SensorRow)>) -> bool {
        let mut e = self.lock();
        e.writing[w.stripe] -= 1;
        let certain = e.undropped_since(w.stripe, w.epoch) && self.live.load(Ordering::SeqCst);
        let Some((c, row)) = stored.filter(|_| certain) else {
            e.drop_stripe(w.stripe);
            e.map.remove(&w.sensor_id);
            return false;
        };
        // Reads that began before this end may not have seen the write.
        e.stamp(w.stripe);
        let held = e.map.get(&w.sensor_id).cloned();
        if held
            .as_ref()
            .is_some_and(|h| h.count() > row.calibration_count)
        {
            // A later state is held: this row is already out of date.
            return held.is_some_and(|h| h.known().is_some());
        }
        let count = row.calibration_count;
        let cached = held.as_ref().and_then(Held::known).map(|s| &s.latest);
        match row.summary(std::iter::once(&c).chain(cached)) {
            Some(s) => {
                self.put(&mut e, &w.sensor_id, Held::Known(Arc::new(s)));
                true
            }
            // Another write of this state knows its latest, or none here
            // (of a state held, the cached latest is the row's).
            None => {
                self.put(&mut e, &w.sensor_id, Held::AtLeast(count));
                false
            }
        }
    }

    /// Whether reads may use the cache now.
    pub fn is_live(&self) -> bool {
        self.live.load(Ordering::SeqCst)
    }

    /// Sensors held now (summaries, and floors left by writes).
    pub fn len(&self) -> usize {
        self.lock().map.len()
    }

    /// Whether nothing is cached.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether `sensor_id`'s summary is cached now.
    pub fn contains(&self, sensor_id: &str) -> bool {
        self.lock()
            .map
            .get(sensor_id)
            .is_some_and(|h| h.known().is_some())
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
mod tests;
