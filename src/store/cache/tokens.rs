//! Issued tokens held in memory, so that a request carrying one (a
//! station's, a dashboard's, a control system's) is authenticated without a
//! database round trip.
//!
//! What is cached is the stored record — its secret's hash, role, station
//! and revocation — by id; the secret a request presents is verified
//! against it on every request, as before. Only tokens that exist are
//! cached: an unknown id is asked of the database each time. The rules that
//! keep a revocation effective:
//!
//! * a revocation through this process drops the token after the database
//!   answered and before the revocation is answered;
//! * a read racing a revocation cannot put back what it replaced: every
//!   drop ticks a clock, and a read fills only if the clock did not move
//!   between its start and its end;
//! * revocations through other processes (replicas sharing PostgreSQL)
//!   arrive as notifications on [`CHANNEL`] (migration 0004), which the
//!   sensor cache's listener also hears; the cache is used only while that
//!   listener is connected, as the sensor cache is;
//! * bounded: at most [`CAPACITY`] tokens; when full, an arbitrary one
//!   makes room.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};

use uuid::Uuid;

use crate::domain::tokens::TokenRecord;

/// Tokens cached at most.
pub const CAPACITY: usize = 4096;

/// The PostgreSQL channel a token's change is notified on.
pub const CHANNEL: &str = "accelcal_tokens";

/// The cached tokens and what guards them.
#[derive(Debug)]
pub struct TokenCache {
    inner: Mutex<Entries>,
    live: AtomicBool,
    capacity: usize,
}

#[derive(Debug, Default)]
struct Entries {
    map: HashMap<Uuid, TokenRecord>,
    /// Ticked by every drop and reset.
    epoch: u64,
}

impl TokenCache {
    /// An empty cache of at most `capacity` tokens, live or not.
    pub fn new(capacity: usize, live: bool) -> Self {
        TokenCache {
            inner: Mutex::new(Entries::default()),
            live: AtomicBool::new(live),
            capacity,
        }
    }

    fn lock(&self) -> MutexGuard<'_, Entries> {
        // Plain data: a panic elsewhere cannot leave it half-updated.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Drops what is cached of token `id`.
    pub fn invalidate(&self, id: Uuid) {
        let mut e = self.lock();
        e.epoch += 1;
        e.map.remove(&id);
    }

    /// Empties the cache and makes it usable (or not) from now on.
    pub fn reset(&self, live: bool) {
        let mut e = self.lock();
        e.epoch += 1;
        e.map.clear();
        self.live.store(live, Ordering::SeqCst);
    }

    /// The tick a read starts at, or `None` when the cache is not live.
    pub(super) fn begin(&self) -> Option<u64> {
        let e = self.lock();
        self.live.load(Ordering::SeqCst).then_some(e.epoch)
    }

    pub(super) fn get(&self, id: Uuid) -> Option<TokenRecord> {
        if !self.live.load(Ordering::SeqCst) {
            return None;
        }
        self.lock().map.get(&id).cloned()
    }

    /// Keeps what a read that began at `epoch` found, unless anything was
    /// dropped since.
    pub(super) fn fill(&self, epoch: u64, record: &TokenRecord) {
        let mut e = self.lock();
        if e.epoch != epoch || !self.live.load(Ordering::SeqCst) {
            return;
        }
        if e.map.len() >= self.capacity
            && !e.map.contains_key(&record.id)
            && let Some(victim) = e.map.keys().next().copied()
        {
            e.map.remove(&victim);
        }
        e.map.insert(record.id, record.clone());
    }

    /// Whether reads may use the cache now.
    pub fn is_live(&self) -> bool {
        self.live.load(Ordering::SeqCst)
    }

    /// Whether token `id` is cached now.
    pub fn contains(&self, id: Uuid) -> bool {
        self.lock().map.contains_key(&id)
    }

    /// Tokens cached now.
    pub fn len(&self) -> usize {
        self.lock().map.len()
    }

    /// Whether nothing is cached.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::auth::Role;
    use crate::domain::timestamp::Timestamp;

    fn record(id: u128) -> TokenRecord {
        TokenRecord {
            id: Uuid::from_u128(id),
            secret_hash: vec![7; 32],
            role: Role::Reader,
            station_id: None,
            label: None,
            holder: None,
            created_at: Timestamp::parse("2026-01-01T00:00:00Z").unwrap(),
            revoked_at: None,
        }
    }

    #[test]
    fn a_read_that_raced_a_revocation_does_not_fill() {
        let c = TokenCache::new(8, true);
        let epoch = c.begin().unwrap();
        c.invalidate(Uuid::from_u128(1));
        c.fill(epoch, &record(1));
        assert!(!c.contains(Uuid::from_u128(1)));
        c.fill(c.begin().unwrap(), &record(1));
        assert_eq!(c.get(Uuid::from_u128(1)), Some(record(1)));
        c.invalidate(Uuid::from_u128(1));
        assert_eq!(c.get(Uuid::from_u128(1)), None);
    }

    #[test]
    fn a_cache_that_is_not_live_neither_answers_nor_fills() {
        let c = TokenCache::new(8, true);
        c.fill(c.begin().unwrap(), &record(1));
        c.reset(false);
        assert!(c.is_empty());
        assert!(c.begin().is_none());
        c.reset(true);
        let epoch = c.begin().unwrap();
        c.reset(false);
        c.fill(epoch, &record(1));
        assert!(c.is_empty());
        c.reset(true);
        c.fill(c.begin().unwrap(), &record(1));
        c.reset(false);
        assert_eq!(
            c.get(Uuid::from_u128(1)),
            None,
            "a cache not live answers nothing"
        );
    }

    #[test]
    fn the_cache_holds_at_most_its_capacity() {
        let c = TokenCache::new(3, true);
        for i in 0..10 {
            c.fill(c.begin().unwrap(), &record(i));
            assert!(c.len() <= 3);
        }
        assert!(c.contains(Uuid::from_u128(9)));
    }
}
