//! Failed authentications, throttled per client address.
//!
//! Each address (an IPv4 address, or an IPv6 /64: one host's share of a
//! network) has a bucket of [`BURST`] failures (configurable) that refills by one every
//! [`REFILL`]. A failure takes one; while the bucket is empty, a request from
//! that address is answered 429 with `Retry-After` *before* its credential is
//! looked up — unless the credential can be judged without the database:
//! the configured admin token, or a token whose id succeeded recently
//! ([`Throttle::trusted`], any address). So an attacker sharing an address
//! with a token holder cannot lock the holder out once the holder's token
//! has been used since the server started; a token never used since then
//! waits for the bucket to refill like any other request from that address.
//! A valid credential never takes from the bucket.
//!
//! Bounded: at most [`MAX_ADDRESSES`] buckets (full ones are forgotten first,
//! then the stalest) and [`MAX_TRUSTED`] trusted ids (forgotten all at once
//! when full: the next request of each is judged again).

use std::collections::{HashMap, HashSet};
use std::net::IpAddr;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Failures an address may make in a burst, by default.
pub const BURST: u32 = 20;
/// One failure forgiven per this interval (20 a minute, sustained).
pub const REFILL: Duration = Duration::from_secs(3);
/// Addresses tracked at once.
pub const MAX_ADDRESSES: usize = 65_536;
/// Token ids remembered as recently valid.
pub const MAX_TRUSTED: usize = 65_536;

/// An address as throttled: IPv4 whole, IPv6 by its /64 prefix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AddrKey(u128);

impl From<IpAddr> for AddrKey {
    fn from(ip: IpAddr) -> Self {
        match ip {
            IpAddr::V4(v4) => AddrKey(u128::from(u32::from(v4))),
            IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
                Some(v4) => AddrKey(u128::from(u32::from(v4))),
                None => AddrKey(((u128::from(v6) >> 64) << 64) | (1 << 63)),
            },
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Bucket {
    /// Failures still allowed, as of `at`.
    left: u32,
    at: Instant,
}

impl Bucket {
    /// The bucket refilled up to `now`, holding at most `burst`.
    fn at(self, now: Instant, burst: u32) -> Bucket {
        let gained = (now.saturating_duration_since(self.at).as_millis() / REFILL.as_millis())
            .min(u128::from(burst)) as u32;
        let left = (self.left + gained).min(burst);
        Bucket {
            left,
            // A full bucket gains nothing more until a failure takes from it.
            at: if left == burst {
                now
            } else {
                self.at + REFILL * gained
            },
        }
    }
}

/// The throttle's state: per-address buckets and recently valid token ids.
#[derive(Debug)]
pub struct Throttle {
    burst: u32,
    buckets: Mutex<HashMap<AddrKey, Bucket>>,
    trusted: Mutex<HashSet<uuid::Uuid>>,
}

impl Default for Throttle {
    fn default() -> Self {
        Throttle::new(BURST)
    }
}

impl Throttle {
    /// A throttle allowing `burst` failures per address.
    pub fn new(burst: u32) -> Self {
        Throttle {
            burst: burst.max(1),
            buckets: Mutex::default(),
            trusted: Mutex::default(),
        }
    }

    /// Seconds until `addr` may fail again, or `None` when it may now.
    pub fn blocked(&self, addr: AddrKey, now: Instant) -> Option<u64> {
        let buckets = self.buckets.lock().expect("throttle lock");
        let b = buckets.get(&addr)?.at(now, self.burst);
        (b.left == 0).then(|| {
            let next = b.at + REFILL;
            next.saturating_duration_since(now).as_secs().max(1)
        })
    }

    /// Records a failed authentication from `addr`.
    pub fn failed(&self, addr: AddrKey, now: Instant) {
        let mut buckets = self.buckets.lock().expect("throttle lock");
        if buckets.len() >= MAX_ADDRESSES && !buckets.contains_key(&addr) {
            buckets.retain(|_, b| b.at(now, self.burst).left < self.burst);
            if buckets.len() >= MAX_ADDRESSES {
                let stalest = buckets.iter().min_by_key(|(_, b)| b.at).map(|(k, _)| *k);
                if let Some(k) = stalest {
                    buckets.remove(&k);
                }
            }
        }
        let b = buckets.entry(addr).or_insert(Bucket {
            left: self.burst,
            at: now,
        });
        let mut refreshed = b.at(now, self.burst);
        refreshed.left = refreshed.left.saturating_sub(1);
        *b = refreshed;
    }

    /// Whether token `id` authenticated successfully since the server started
    /// (or since the set was last cleared).
    pub fn trusted(&self, id: uuid::Uuid) -> bool {
        self.trusted.lock().expect("throttle lock").contains(&id)
    }

    /// Records that token `id` authenticated successfully.
    pub fn succeeded(&self, id: uuid::Uuid) {
        let mut trusted = self.trusted.lock().expect("throttle lock");
        if trusted.contains(&id) {
            return;
        }
        if trusted.len() >= MAX_TRUSTED {
            trusted.clear();
        }
        trusted.insert(id);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(s: &str) -> AddrKey {
        AddrKey::from(s.parse::<IpAddr>().unwrap())
    }

    #[test]
    fn a_burst_is_allowed_then_one_failure_per_refill() {
        let t = Throttle::default();
        let a = addr("192.0.2.1");
        let t0 = Instant::now();
        for _ in 0..BURST {
            assert_eq!(t.blocked(a, t0), None);
            t.failed(a, t0);
        }
        assert_eq!(t.blocked(a, t0), Some(REFILL.as_secs()));
        // Another address is not affected.
        assert_eq!(t.blocked(addr("192.0.2.2"), t0), None);
        // One refill later, one more failure is allowed, then blocked again.
        let t1 = t0 + REFILL;
        assert_eq!(t.blocked(a, t1), None);
        t.failed(a, t1);
        assert!(t.blocked(a, t1).is_some());
        // A long quiet time refills the whole burst, never more.
        let t2 = t1 + REFILL * (BURST * 10);
        for _ in 0..BURST {
            assert_eq!(t.blocked(a, t2), None);
            t.failed(a, t2);
        }
        assert!(t.blocked(a, t2).is_some());
    }

    #[test]
    fn ipv6_hosts_are_keyed_by_their_slash_64() {
        assert_eq!(addr("2001:db8:1:2::1"), addr("2001:db8:1:2:ffff::9"));
        assert_ne!(addr("2001:db8:1:2::1"), addr("2001:db8:1:3::1"));
        assert_eq!(addr("::ffff:192.0.2.1"), addr("192.0.2.1"));
        assert_ne!(addr("::1"), addr("0.0.0.1"));
    }

    #[test]
    fn addresses_tracked_are_bounded() {
        let t = Throttle::default();
        let now = Instant::now();
        for i in 0..(MAX_ADDRESSES as u32 + 10) {
            t.failed(AddrKey(u128::from(i)), now);
        }
        assert!(t.buckets.lock().unwrap().len() <= MAX_ADDRESSES);
    }

    #[test]
    fn trusted_ids_are_remembered_and_bounded() {
        let t = Throttle::default();
        let id = uuid::Uuid::now_v7();
        assert!(!t.trusted(id));
        t.succeeded(id);
        assert!(t.trusted(id));
        for _ in 0..MAX_TRUSTED {
            t.succeeded(uuid::Uuid::now_v7());
        }
        assert!(t.trusted.lock().unwrap().len() <= MAX_TRUSTED);
    }
}
