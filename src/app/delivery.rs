//! Webhook delivery (issue 47 item 3): each replica runs one dispatcher
//! that delivers the live events ([`super::events`]) to the registered
//! endpoints, signed by Standard Webhooks ([`crate::domain::webhooks`]).
//!
//! **The outbox is the audit trail.** Every act's entry is written in the
//! act's own transaction, and an endpoint's `cursor` is the last entry it
//! was handed (or that was not for it): what lies after it is what the
//! endpoint still has to receive. Nothing an act does waits for a
//! delivery, and nothing acknowledged can be missed — a crash at any
//! moment leaves the cursor at or before the last event delivered, so the
//! event in flight is delivered again, with the same `webhook-id`.
//!
//! **One attempt at a time.** A dispatcher takes an endpoint with events
//! due by a lease in the database ([`crate::store::Webhooks::claim_webhook`]),
//! attempts its next event, and records the outcome with the lease's end;
//! another replica takes the endpoint only after that (or after the lease
//! expired, the holder having died). So an endpoint receives its events in
//! sequence order, one at a time, and no event is attempted twice at once.
//!
//! **Targets.** Redirects are not followed, each attempt has a timeout, and
//! names are resolved by a resolver that refuses private and loopback
//! addresses unless the operator allows them — the check made at
//! registration, made again where the connection is made.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::{Notify, Semaphore, watch};
use uuid::Uuid;

use super::events::since;
use crate::domain::events::LiveEvent;
use crate::domain::review::Basis;
use crate::domain::timestamp::Timestamp;
use crate::domain::webhooks::{
    Delivery, Endpoint, Outcome, Payload, Retry, message_id, refused_address,
};
use crate::store::{Settle, Store};

/// How webhooks are delivered: each a flag.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Backoff and give-up age (`--webhook-retry-base`, `--webhook-retry-cap`,
    /// `--webhook-max-age`).
    pub retry: Retry,
    /// Each attempt's timeout (`--webhook-timeout`).
    pub timeout: Duration,
    /// Whether private and loopback targets are allowed
    /// (`--webhook-allow-private`).
    pub allow_private: bool,
    /// How often the dispatcher looks for due deliveries besides being
    /// woken by this replica's own acts.
    pub poll: Duration,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            retry: Retry {
                base: Duration::from_secs(5),
                cap: Duration::from_secs(3600),
                max_age: Duration::from_secs(3 * 24 * 3600),
            },
            timeout: Duration::from_secs(10),
            allow_private: false,
            poll: super::events::POLL,
        }
    }
}

/// Endpoints delivered to at once by one replica at most.
pub const CONCURRENT: usize = 16;

/// Trail entries read for an endpoint at once: its events among them are
/// delivered under one lease.
pub const PAGE: usize = 100;

/// How long a target's name may take to resolve.
pub const RESOLVE_TIMEOUT: Duration = Duration::from_secs(5);

/// How far a lease outlasts its attempt's timeout.
pub const LEASE_MARGIN: Duration = Duration::from_secs(5);

/// Why a target is refused, if it is: an IP literal that is private or
/// loopback (names are judged by the resolver, after resolution).
pub fn refused_literal(url: &url::Url) -> Option<String> {
    let ip = match url.host()? {
        url::Host::Ipv4(ip) => std::net::IpAddr::V4(ip),
        url::Host::Ipv6(ip) => std::net::IpAddr::V6(ip),
        url::Host::Domain(_) => return None,
    };
    refused_address(ip).map(|why| refusal(ip, why))
}

fn refusal(ip: std::net::IpAddr, why: &str) -> String {
    format!(
        "its address {ip} is {why}: refused unless the operator allows private targets \
         (--webhook-allow-private)"
    )
}

/// Resolves `host`'s names and refuses it when any address is private or
/// loopback; an error says why.
pub async fn check_host(url: &url::Url) -> Result<(), String> {
    if let Some(why) = refused_literal(url) {
        return Err(why);
    }
    let Some(url::Host::Domain(name)) = url.host() else {
        return Ok(());
    };
    resolve(name).await.map(|_| ())
}

/// `name`'s addresses, none of them refused.
async fn resolve(name: &str) -> Result<Vec<SocketAddr>, String> {
    let lookup = tokio::time::timeout(RESOLVE_TIMEOUT, tokio::net::lookup_host((name, 0)))
        .await
        .map_err(|_| format!("its host `{name}` did not resolve within {RESOLVE_TIMEOUT:?}"))?;
    let addrs: Vec<SocketAddr> = lookup
        .map_err(|e| format!("its host `{name}` does not resolve ({e})"))?
        .collect();
    if addrs.is_empty() {
        return Err(format!("its host `{name}` has no address"));
    }
    if let Some((ip, why)) = addrs
        .iter()
        .find_map(|a| refused_address(a.ip()).map(|why| (a.ip(), why)))
    {
        return Err(refusal(ip, why));
    }
    Ok(addrs)
}

/// The resolver of delivery connections: [`resolve`], unless private
/// targets are allowed.
struct Guarded;

impl reqwest::dns::Resolve for Guarded {
    fn resolve(&self, name: reqwest::dns::Name) -> reqwest::dns::Resolving {
        let name = name.as_str().to_owned();
        Box::pin(async move {
            let addrs = resolve(&name)
                .await
                .map_err(Box::<dyn std::error::Error + Send + Sync>::from)?;
            Ok(Box::new(addrs.into_iter()) as reqwest::dns::Addrs)
        })
    }
}

/// The HTTP client of deliveries: no redirects, the timeout per attempt,
/// the guarded resolver unless private targets are allowed.
fn client(s: &Settings) -> reqwest::Client {
    let mut b = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .timeout(s.timeout)
        .user_agent(concat!("accelcal/", env!("CARGO_PKG_VERSION"), " webhooks"));
    if !s.allow_private {
        b = b.dns_resolver(Arc::new(Guarded));
    }
    b.build().expect("a client of static settings")
}

/// Starts this replica's dispatcher; it runs until `closed` turns true,
/// then ends the attempts in flight (their leases expire, and their events
/// are attempted again: at least once) and lets go of the store. `wake`
/// wakes it (an endpoint registered or redelivered).
pub fn start(
    store: Arc<dyn Store>,
    basis: Basis,
    settings: Settings,
    wake: Arc<Notify>,
    closed: watch::Receiver<bool>,
) -> tokio::task::JoinHandle<()> {
    let d = Dispatcher {
        client: client(&settings),
        store,
        basis,
        settings,
        holder: Uuid::now_v7(),
        wake,
        slots: Arc::new(Semaphore::new(CONCURRENT)),
    };
    tokio::spawn(d.run(closed))
}

#[derive(Clone)]
struct Dispatcher {
    store: Arc<dyn Store>,
    /// The service's basis, on which payloads tell what the coefficients
    /// did.
    basis: Basis,
    settings: Settings,
    client: reqwest::Client,
    holder: Uuid,
    wake: Arc<Notify>,
    slots: Arc<Semaphore>,
}

impl Dispatcher {
    async fn run(self, mut closed: watch::Receiver<bool>) {
        let mut grew = self.store.trail_grew();
        let mut attempts = tokio::task::JoinSet::new();
        let mut tick = tokio::time::interval(self.settings.poll);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                _ = tick.tick() => {}
                () = super::events::grown(&mut grew) => {}
                () = self.wake.notified() => {}
                _ = closed.changed() => {
                    attempts.shutdown().await;
                    return;
                }
            }
            while attempts.try_join_next().is_some() {}
            if let Err(e) = self.round(&mut attempts).await {
                tracing::warn!(error = %e, "webhooks: the endpoints could not be read");
            }
            tokio::time::sleep(super::events::GAP).await;
        }
    }

    /// Claims every endpoint with a delivery due and attempts each, at most
    /// [`CONCURRENT`] at once.
    async fn round(
        &self,
        attempts: &mut tokio::task::JoinSet<()>,
    ) -> Result<(), crate::store::StoreError> {
        let head = self.store.audit_head().await?;
        let endpoints = self.store.webhooks().await?;
        let now = Timestamp::now();
        let backlog: i64 = endpoints.iter().map(|e| (head - e.cursor).max(0)).sum();
        metrics::gauge!("accelcal_webhook_backlog_entries").set(backlog as f64);
        metrics::gauge!("accelcal_webhook_failing_endpoints")
            .set(endpoints.iter().filter(|e| e.failed > 0).count() as f64);
        if !endpoints
            .iter()
            .any(|e| e.cursor < head && e.next_attempt_at <= now)
        {
            return Ok(());
        }
        loop {
            let Ok(slot) = self.slots.clone().acquire_owned().await else {
                return Ok(());
            };
            let now = Timestamp::now();
            let Some(endpoint) = self
                .store
                .claim_webhook(head, now, (self.holder, self.lease_until(now)))
                .await?
            else {
                return Ok(());
            };
            let this = self.clone();
            attempts.spawn(async move {
                let id = endpoint.def.webhook_id.clone();
                if let Err(e) = this.deliver(endpoint).await {
                    tracing::warn!(webhook = %id, error = %e, "webhooks: a delivery could not be recorded");
                }
                drop(slot);
                // Its next event may be due at once.
                this.wake.notify_one();
            });
        }
    }

    /// Attempts the endpoint's next events in order — up to [`PAGE`]
    /// entries' worth, under one lease renewed after each — until one
    /// fails, or moves its cursor past entries not for it; records where it
    /// stands after each.
    async fn deliver(&self, e: Endpoint) -> Result<(), crate::store::StoreError> {
        let id = e.def.webhook_id.clone();
        let (events, last) =
            since(self.store.as_ref(), self.basis, e.cursor, &e.filter(), PAGE).await?;
        if events.is_empty() {
            let s = Settle {
                cursor: last,
                failed: 0,
                next_attempt_at: e.next_attempt_at,
                delivery: None,
                hold_until: None,
            };
            self.store.settle_webhook(id, self.holder, s).await?;
            return Ok(());
        }
        let gauge =
            metrics::gauge!("accelcal_webhook_undelivered_age_seconds", "webhook_id" => id.clone());
        let mut failed = e.failed;
        for (i, event) in events.iter().enumerate() {
            let d = self.attempt(&e, failed, event).await;
            let now = d.at;
            metrics::counter!("accelcal_webhook_attempts_total", "outcome" => d.outcome.as_str())
                .increment(1);
            let settle = match d.outcome {
                Outcome::Delivered | Outcome::Abandoned => {
                    gauge.set(0.0);
                    failed = 0;
                    let more = i + 1 < events.len();
                    Settle {
                        // All of the page handled: past its other entries too.
                        cursor: if more { event.seq } else { last },
                        failed,
                        next_attempt_at: now,
                        delivery: Some(d),
                        hold_until: more.then(|| self.lease_until(Timestamp::now())),
                    }
                }
                Outcome::Failed => {
                    gauge.set((now.unix_micros() - event.at.unix_micros()) as f64 / 1e6);
                    failed += 1;
                    let wait = self.settings.retry.delay(failed as u32, unit());
                    Settle {
                        cursor: event.seq - 1,
                        failed,
                        next_attempt_at: Timestamp::from_unix_micros(
                            now.unix_micros() + wait.as_micros() as i64,
                        )
                        .unwrap_or(now),
                        delivery: Some(d),
                        hold_until: None,
                    }
                }
            };
            let keep = settle.hold_until.is_some();
            let held = self
                .store
                .settle_webhook(id.clone(), self.holder, settle)
                .await?;
            if !(held && keep) {
                return Ok(()); // failed, done, or the lease was lost (redelivered, deleted)
            }
        }
        Ok(())
    }

    /// When a lease taken at `now` ends: the attempt's timeout and a margin.
    fn lease_until(&self, now: Timestamp) -> Timestamp {
        let lease = self.settings.timeout + LEASE_MARGIN;
        Timestamp::from_unix_micros(now.unix_micros() + lease.as_micros() as i64).unwrap_or(now)
    }

    /// One signed POST of `event` to `e`, its attempt after `failed`
    /// failures, and how it went.
    async fn attempt(&self, e: &Endpoint, failed: i64, event: &LiveEvent) -> Delivery {
        let at = Timestamp::now();
        let message = message_id(event.seq);
        let body = serde_json::to_vec(&Payload::of(event)).expect("an event serialises");
        let ts = at.unix_micros().div_euclid(1_000_000);
        let signature = e.secrets.header(at, &message, ts, &body);
        let started = Instant::now();
        let refused = url::Url::parse(&e.def.url)
            .ok()
            .and_then(|u| refused_literal(&u))
            .filter(|_| !self.settings.allow_private);
        let (status, error) = match refused {
            Some(why) => (None, Some(format!("the URL {why}"))),
            None => {
                let sent = self
                    .client
                    .post(&e.def.url)
                    .header("content-type", "application/json")
                    .header("webhook-id", &message)
                    .header("webhook-timestamp", ts.to_string())
                    .header("webhook-signature", signature)
                    .body(body)
                    .send()
                    .await;
                match sent {
                    Ok(res) => (Some(i64::from(res.status().as_u16())), None),
                    Err(err) => (None, Some(chain(&err))),
                }
            }
        };
        let ok = status.is_some_and(|s| (200..300).contains(&s));
        let outcome = if ok {
            Outcome::Delivered
        } else if self.settings.retry.expired(event.at, Timestamp::now()) {
            Outcome::Abandoned
        } else {
            Outcome::Failed
        };
        Delivery {
            event_seq: event.seq,
            message_id: message,
            attempt: failed + 1,
            at,
            outcome,
            status,
            error,
            duration_ms: started.elapsed().as_millis() as i64,
        }
    }
}

/// An error and its causes, `: `-separated (reqwest's own message hides
/// the cause: a timeout, a refused connection, a refused address).
fn chain(e: &dyn std::error::Error) -> String {
    let mut out = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        out.push_str(": ");
        out.push_str(&c.to_string());
        cause = c.source();
    }
    out
}

/// A uniform draw in [0, 1) for the jitter.
fn unit() -> f64 {
    let mut b = [0u8; 4];
    if getrandom::fill(&mut b).is_err() {
        return 0.5;
    }
    f64::from(u32::from_le_bytes(b)) / (f64::from(u32::MAX) + 1.0)
}
