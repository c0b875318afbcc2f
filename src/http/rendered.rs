//! Answers rendered once per stored calibration and kept by its id.
//!
//! A stored calibration never changes (both engines refuse an update of its
//! row), so anything rendered from it alone — its coefficients document —
//! cannot go stale, in this process or across replicas: an id means the
//! same row everywhere. What also shows its state (a summary in a history
//! page) is kept by id *and* state, the state being read with the ids.
//! Which calibrations a read needs (the latest, a page) is still asked of
//! the store on every read.
//!
//! Kept because it pays: without the kept renderings (and with axum's
//! `Json`), a 20-item history page took 1 242 700 instructions instead of
//! 188 700, a coefficients read 123 900 instead of 107 100 (callgrind at
//! `info`, `benches/instructions.sh`).

use std::collections::HashMap;
use std::hash::Hash;
use std::sync::Mutex;

use axum::http::HeaderValue;
use bytes::Bytes;
use uuid::Uuid;

use crate::domain::timestamp::Timestamp;

/// The `Content-Type` of a rendered JSON answer.
pub static APPLICATION_JSON: HeaderValue = HeaderValue::from_static("application/json");

/// Renderings by calibration id (or by id and whatever else they show, `K`),
/// at most `capacity`; when full, an arbitrary one makes room. A rendering
/// that holds a time-dependent part (a status) is kept with the last
/// instant it is right at.
#[derive(Debug)]
pub struct ById<K = Uuid> {
    map: Mutex<HashMap<K, (Bytes, Option<Timestamp>)>>,
    capacity: usize,
}

impl<K: Eq + Hash + Clone> ById<K> {
    /// Empty, keeping at most `capacity` renderings.
    pub fn new(capacity: usize) -> Self {
        ById {
            map: Mutex::new(HashMap::new()),
            capacity,
        }
    }

    /// The kept rendering of calibration `id`, if any (kept for ever).
    pub fn get(&self, id: &K) -> Option<Bytes> {
        self.lock().get(id).map(|(body, _)| body.clone())
    }

    /// The kept rendering of calibration `id`, if any and still right at
    /// `now`.
    pub fn get_at(&self, id: &K, now: Timestamp) -> Option<Bytes> {
        match self.lock().get(id) {
            Some((body, until)) if until.is_none_or(|t| now <= t) => Some(body.clone()),
            _ => None,
        }
    }

    /// Keeps `body` as the rendering of calibration `id`, right for ever.
    pub fn insert(&self, id: K, body: Bytes) {
        self.insert_until(id, body, None);
    }

    /// Keeps `body` as the rendering of calibration `id`, right up to
    /// `until` (for ever when `None`).
    pub fn insert_until(&self, id: K, body: Bytes, until: Option<Timestamp>) {
        let mut map = self.lock();
        if map.len() >= self.capacity
            && !map.contains_key(&id)
            && let Some(victim) = map.keys().next().cloned()
        {
            map.remove(&victim);
        }
        map.insert(id, (body, until));
    }

    /// Renderings kept now.
    pub fn len(&self) -> usize {
        self.lock().len()
    }

    /// Whether none is.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether calibration `id`'s rendering is kept.
    pub fn contains(&self, id: &K) -> bool {
        self.lock().contains_key(id)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<K, (Bytes, Option<Timestamp>)>> {
        // Plain data: a panic elsewhere cannot leave it half-updated.
        self.map.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_at_most_its_capacity_and_the_newest() {
        let kept: ById = ById::new(3);
        assert!(kept.is_empty());
        for id in 0..10u128 {
            kept.insert(Uuid::from_u128(id), Bytes::from(id.to_string()));
            assert!(kept.len() <= 3);
        }
        assert_eq!(kept.len(), 3);
        let now = Timestamp::parse("2026-01-01T00:00:00Z").unwrap();
        assert_eq!(kept.get(&Uuid::from_u128(9)), Some(Bytes::from("9")));
        // Putting one kept again evicts nothing.
        kept.insert(Uuid::from_u128(9), Bytes::from("9"));
        assert_eq!(kept.len(), 3);
        assert!(kept.contains(&Uuid::from_u128(9)));
        assert_eq!(kept.get(&Uuid::from_u128(100)), None);
        // One right until a time is served up to it, not after.
        let id = Uuid::from_u128(9);
        kept.insert_until(id, Bytes::from("soon"), Some(now));
        assert_eq!(kept.get_at(&id, now), Some(Bytes::from("soon")));
        assert_eq!(kept.get_at(&id, now.plus_seconds(1)), None);
    }
}
