//! Webhooks (issue 47 item 3): endpoints an admin registers, and the rules
//! of delivering the live events ([`super::events`]) to them by Standard
//! Webhooks 1.0.
//!
//! **Signing.** Every request carries `webhook-id` (the event's
//! [`message_id`], the same on every retry and on a redelivery),
//! `webhook-timestamp` (the attempt's Unix time, seconds) and
//! `webhook-signature`: `v1,` then the standard base64 of
//! HMAC-SHA256(key, `id.timestamp.body`), the key being the base64-decoded
//! part of the secret after `whsec_` ([`signature`]). While a rotated-out
//! secret still signs (an overlap the admin chose), the header holds both
//! signatures, the current one first, separated by a space.
//!
//! **Retries.** A failed attempt (no answer within the timeout, or any
//! status but 2xx) is tried again after
//! `min(base · 2^(n−1), cap) · (1 + j)`, `n` the failed attempts so far and
//! `j` uniform in [−0.2, 0.2] ([`Retry::delay`]), until the event is older
//! than the maximum age, when it is given up (logged as `abandoned`) and
//! the next is tried. An endpoint receives its events in sequence order,
//! one at a time: the next waits for the one before it.
//!
//! **Targets.** A URL is `http` or `https`, with a host, and no user name,
//! password or fragment; an address that is loopback, private, link-local,
//! shared (CGNAT), unspecified, multicast or reserved is refused
//! ([`refused_address`]) unless the operator allows them — at
//! registration and again, after name resolution, at every attempt.

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};
use std::time::Duration;

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;
use hmac::{Hmac, KeyInit, Mac};
use serde::{Deserialize, Serialize};
use sha2::Sha256;
use utoipa::ToSchema;

use super::events::{EventType, Filter, LiveEvent};
use super::field::{Errors, Invalid, Loc};
use super::limits::{MAX_DESCRIPTION_CHARS, MAX_ID_CHARS};
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// The prefix of a Standard Webhooks secret.
pub const SECRET_PREFIX: &str = "whsec_";

/// Bytes of a generated secret's key (Standard Webhooks asks 24 to 64).
pub const KEY_BYTES: usize = 32;

/// Characters of a URL at most.
pub const MAX_URL_CHARS: usize = 2048;

/// Event types and sensors an endpoint may name, each at most.
pub const MAX_NAMED: usize = 100;

/// Delivery attempts kept in an endpoint's log (the newest).
pub const LOG_KEPT: i64 = 1000;

/// How long a rotated-out secret signs beside the new one, by default (24 h).
pub const DEFAULT_OVERLAP_S: i64 = 24 * 3600;

/// How long it may at most (7 days).
pub const MAX_OVERLAP_S: i64 = 7 * 24 * 3600;

/// The body of `PUT /v1/webhooks/{webhook_id}`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WebhookBody {
    /// Where to POST the events: `http` or `https`, no user name or
    /// password; a loopback or private address only where the operator
    /// allows them.
    pub url: String,
    /// Only events of these types (none: every type).
    #[serde(default)]
    pub event_types: Vec<EventType>,
    /// Only events of these sensors (none: every sensor's, and those of
    /// no sensor).
    #[serde(default)]
    pub sensors: Vec<String>,
    /// What it is for (one line, at most 256 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_description)]
    pub description: Option<String>,
}

/// What an admin asked an endpoint to be, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Definition {
    /// Its id.
    pub webhook_id: String,
    /// Its URL, parsed and written back normalised.
    pub url: String,
    /// Its event types (none: all).
    pub event_types: Vec<EventType>,
    /// Its sensors (none: all).
    pub sensors: Vec<String>,
    /// What it is for.
    pub description: Option<String>,
}

impl WebhookBody {
    /// Checks the body; every problem is reported at its field. Whether the
    /// host's addresses are allowed is the caller's to judge
    /// ([`refused_address`]), after resolving it.
    pub fn check(self, webhook_id: String) -> Result<(Definition, url::Url), Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        let url = match target(&self.url) {
            Ok(u) => Some(u),
            Err(why) => {
                errors.add(root.key("url"), why);
                None
            }
        };
        if self.event_types.len() > MAX_NAMED {
            errors.add(
                root.key("event_types"),
                format!("names more than {MAX_NAMED} types"),
            );
        }
        if self.sensors.len() > MAX_NAMED {
            errors.add(
                root.key("sensors"),
                format!("names more than {MAX_NAMED} sensors"),
            );
        }
        let sensors = root.key("sensors");
        for (i, s) in self.sensors.iter().enumerate().take(MAX_NAMED) {
            if let Err(why) = check_str(s, MAX_ID_CHARS, Chars::Identifier) {
                errors.add(sensors.index(i), why);
            }
        }
        if let Some(d) = &self.description
            && let Err(why) = check_str(d, MAX_DESCRIPTION_CHARS, Chars::Line)
        {
            errors.add(root.key("description"), why);
        }
        let mut event_types = self.event_types;
        event_types.sort_by_key(|t| t.as_str());
        event_types.dedup();
        let mut sensors = self.sensors;
        sensors.sort();
        sensors.dedup();
        errors.finish(|| {
            let url = url.expect("checked");
            (
                Definition {
                    webhook_id,
                    url: url.to_string(),
                    event_types,
                    sensors,
                    description: self.description,
                },
                url,
            )
        })
    }
}

/// Parses a target URL: `http` or `https`, a host, no user name, password
/// or fragment, at most [`MAX_URL_CHARS`].
pub fn target(s: &str) -> Result<url::Url, String> {
    if s.chars().count() > MAX_URL_CHARS {
        return Err(format!("is longer than {MAX_URL_CHARS} characters"));
    }
    let u = url::Url::parse(s).map_err(|e| format!("is not a URL ({e})"))?;
    if !matches!(u.scheme(), "http" | "https") {
        return Err(format!("has scheme `{}`: only http and https", u.scheme()));
    }
    if u.host().is_none() {
        return Err("has no host".into());
    }
    if !u.username().is_empty() || u.password().is_some() {
        return Err("carries a user name or password: put secrets in no URL".into());
    }
    if u.fragment().is_some() {
        return Err("has a fragment (`#…`), which is never sent".into());
    }
    Ok(u)
}

/// Why `ip` is no address to deliver to without the operator's leave, if
/// it is not: loopback, private (RFC 1918, IPv6 unique local), link-local,
/// shared address space (RFC 6598), unspecified, broadcast, multicast,
/// documentation or otherwise reserved. An IPv4 address written as IPv6
/// (`::ffff:a.b.c.d`) is judged as IPv4.
pub fn refused_address(ip: IpAddr) -> Option<&'static str> {
    match ip {
        IpAddr::V4(v4) => refused_v4(v4),
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => refused_v4(v4),
            None => refused_v6(v6),
        },
    }
}

fn refused_v4(ip: Ipv4Addr) -> Option<&'static str> {
    let [a, b, ..] = ip.octets();
    Some(if ip.is_loopback() {
        "loopback"
    } else if ip.is_private() {
        "private"
    } else if ip.is_link_local() {
        "link-local"
    } else if a == 100 && (64..128).contains(&b) {
        "shared (carrier-grade NAT)"
    } else if ip.is_unspecified() || a == 0 {
        "unspecified"
    } else if ip.is_broadcast() || ip.is_multicast() {
        "broadcast or multicast"
    } else if ip.is_documentation() || a >= 240 || (a == 192 && b == 0 && ip.octets()[2] == 0) {
        "reserved"
    } else {
        return None;
    })
}

fn refused_v6(ip: Ipv6Addr) -> Option<&'static str> {
    let first = ip.segments()[0];
    Some(if ip.is_loopback() {
        "loopback"
    } else if ip.is_unspecified() {
        "unspecified"
    } else if first & 0xfe00 == 0xfc00 {
        "private (unique local)"
    } else if first & 0xffc0 == 0xfe80 {
        "link-local"
    } else if ip.is_multicast() {
        "multicast"
    } else if first == 0x2001 && ip.segments()[1] == 0x0db8 {
        "reserved"
    } else {
        return None;
    })
}

/// A Standard Webhooks secret: `whsec_` and the standard base64 of its key.
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(String);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(..)")
    }
}

impl Secret {
    /// A new secret of [`KEY_BYTES`] random bytes.
    pub fn generate() -> Result<Secret, getrandom::Error> {
        let mut key = [0u8; KEY_BYTES];
        getrandom::fill(&mut key)?;
        Ok(Secret(format!("{SECRET_PREFIX}{}", STANDARD.encode(key))))
    }

    /// A secret as stored; `None` when it is not one.
    pub fn parse(s: &str) -> Option<Secret> {
        let key = STANDARD.decode(s.strip_prefix(SECRET_PREFIX)?).ok()?;
        (!key.is_empty()).then(|| Secret(s.to_owned()))
    }

    /// Its text (`whsec_…`), to store and to show once.
    pub fn expose(&self) -> &str {
        &self.0
    }

    fn key(&self) -> Vec<u8> {
        STANDARD
            .decode(&self.0[SECRET_PREFIX.len()..])
            .expect("parsed or generated")
    }
}

/// `v1,` and the standard base64 of HMAC-SHA256 of `id.timestamp.body`
/// under the secret's key.
pub fn signature(secret: &Secret, id: &str, timestamp: i64, body: &[u8]) -> String {
    let mut mac = Hmac::<Sha256>::new_from_slice(&secret.key()).expect("any key length");
    mac.update(id.as_bytes());
    mac.update(b".");
    mac.update(timestamp.to_string().as_bytes());
    mac.update(b".");
    mac.update(body);
    format!("v1,{}", STANDARD.encode(mac.finalize().into_bytes()))
}

/// The secrets an endpoint signs with.
#[derive(Clone, Debug, PartialEq)]
pub struct Secrets {
    /// The one shown at its registration or last rotation.
    pub current: Secret,
    /// The one rotated out, signing beside it until the time given.
    pub previous: Option<(Secret, Timestamp)>,
}

impl Secrets {
    /// The `webhook-signature` header at `now`: the current secret's
    /// signature, then the previous one's while it still signs.
    pub fn header(&self, now: Timestamp, id: &str, timestamp: i64, body: &[u8]) -> String {
        let mut out = signature(&self.current, id, timestamp, body);
        if let Some((old, until)) = &self.previous
            && now < *until
        {
            out.push(' ');
            out.push_str(&signature(old, id, timestamp, body));
        }
        out
    }
}

/// The `webhook-id` of an event: `evt_` and its sequence number.
pub fn message_id(seq: i64) -> String {
    format!("evt_{seq}")
}

/// The body POSTed for an event, Standard Webhooks' shape: its `type`, its
/// `timestamp` (when the act happened) and the event as `data`.
#[derive(Debug, Serialize, ToSchema)]
#[schema(as = WebhookPayload)]
pub struct Payload<'a> {
    /// The event's type.
    #[serde(rename = "type")]
    pub kind: EventType,
    /// When the act happened.
    pub timestamp: Timestamp,
    /// The event, as `GET /v1/events` sends it.
    pub data: &'a LiveEvent,
}

impl<'a> Payload<'a> {
    /// The payload of `e`.
    pub fn of(e: &'a LiveEvent) -> Payload<'a> {
        Payload {
            kind: e.kind,
            timestamp: e.at,
            data: e,
        }
    }
}

/// How failed deliveries are tried again.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Retry {
    /// The delay after the first failure.
    pub base: Duration,
    /// The longest delay.
    pub cap: Duration,
    /// An event older than this is given up.
    pub max_age: Duration,
}

/// The jitter's half-width, a fraction of the delay.
pub const JITTER: f64 = 0.2;

impl Retry {
    /// The delay after the `failed`-th failed attempt (from 1):
    /// `min(base · 2^(failed−1), cap) · (1 + JITTER · (2u − 1))`, `u` in
    /// [0, 1) drawn by the caller.
    pub fn delay(&self, failed: u32, u: f64) -> Duration {
        let doubled = self
            .base
            .saturating_mul(1u32 << failed.saturating_sub(1).min(30));
        doubled
            .min(self.cap)
            .mul_f64(1.0 + JITTER * (2.0 * u.clamp(0.0, 1.0) - 1.0))
    }

    /// Whether an event of `at` is past its age at `now`.
    pub fn expired(&self, at: Timestamp, now: Timestamp) -> bool {
        now.unix_micros() - at.unix_micros() > self.max_age.as_micros() as i64
    }
}

/// An endpoint as stored: what was asked, its secrets, and where its
/// deliveries stand.
#[derive(Clone, Debug, PartialEq)]
pub struct Endpoint {
    /// What an admin asked.
    pub def: Definition,
    /// Its secrets.
    pub secrets: Secrets,
    /// When it was registered.
    pub created_at: Timestamp,
    /// When it was last changed.
    pub updated_at: Timestamp,
    /// The last event handled: delivered, given up, or not for it.
    pub cursor: i64,
    /// Failed attempts at the event after `cursor`.
    pub failed: i64,
    /// When the next attempt is due.
    pub next_attempt_at: Timestamp,
}

impl Endpoint {
    /// The events it takes.
    pub fn filter(&self) -> Filter {
        Filter {
            sensors: self.def.sensors.clone(),
            types: self.def.event_types.clone(),
        }
    }
}

/// An endpoint as served (never its secret).
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct Webhook {
    /// Its id.
    #[schema(value_type = crate::domain::schema::Identifier)]
    pub webhook_id: String,
    /// Where events are POSTed.
    pub url: String,
    /// Only events of these types (empty: all).
    pub event_types: Vec<EventType>,
    /// Only events of these sensors (empty: all).
    pub sensors: Vec<String>,
    /// What it is for.
    pub description: Option<String>,
    /// When it was registered.
    pub created_at: Timestamp,
    /// When it was last changed.
    pub updated_at: Timestamp,
    /// The last event handled (delivered, given up, or not for it): the
    /// next delivered is after it.
    pub delivered_through: i64,
    /// Failed attempts at the next event (0: none failing).
    pub failed_attempts: i64,
    /// When the next attempt is due, if one is failing.
    pub retry_at: Option<Timestamp>,
    /// Until when the rotated-out secret signs beside the current one.
    pub previous_secret_until: Option<Timestamp>,
}

impl From<&Endpoint> for Webhook {
    fn from(e: &Endpoint) -> Webhook {
        Webhook {
            webhook_id: e.def.webhook_id.clone(),
            url: e.def.url.clone(),
            event_types: e.def.event_types.clone(),
            sensors: e.def.sensors.clone(),
            description: e.def.description.clone(),
            created_at: e.created_at,
            updated_at: e.updated_at,
            delivered_through: e.cursor,
            failed_attempts: e.failed,
            retry_at: (e.failed > 0).then_some(e.next_attempt_at),
            previous_secret_until: e.secrets.previous.as_ref().map(|(_, until)| *until),
        }
    }
}

/// How an attempt ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = DeliveryOutcome)]
pub enum Outcome {
    /// The receiver answered 2xx.
    Delivered,
    /// It did not: tried again later.
    Failed,
    /// It did not, and the event is past its age: given up.
    Abandoned,
}

impl Outcome {
    /// Its name as stored and served.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Delivered => "delivered",
            Outcome::Failed => "failed",
            Outcome::Abandoned => "abandoned",
        }
    }

    /// The outcome named `s`.
    pub fn parse(s: &str) -> Option<Outcome> {
        [Outcome::Delivered, Outcome::Failed, Outcome::Abandoned]
            .into_iter()
            .find(|o| o.as_str() == s)
    }
}

/// One delivery attempt, as logged.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Delivery {
    /// The event's sequence number.
    pub event_seq: i64,
    /// Its `webhook-id`.
    pub message_id: String,
    /// Which attempt at it this was (from 1).
    pub attempt: i64,
    /// When it was made.
    pub at: Timestamp,
    /// How it ended.
    pub outcome: Outcome,
    /// The receiver's status, if it answered.
    pub status: Option<i64>,
    /// Why it failed, if it did and the status does not say.
    pub error: Option<String>,
    /// How long it took, in milliseconds.
    pub duration_ms: i64,
}

/// The body of `POST /v1/webhooks/{webhook_id}/secret`.
#[derive(Clone, Debug, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RotateBody {
    /// How long the old secret signs beside the new one, in seconds (0 to
    /// 604 800; default 86 400).
    #[serde(default, deserialize_with = "whole_opt")]
    #[schema(minimum = 0, maximum = 604800)]
    pub overlap_s: Option<i64>,
}

/// The body of `POST /v1/webhooks/{webhook_id}/redeliver`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RedeliverBody {
    /// Deliver again every event of this endpoint after this sequence
    /// number (an event id, at most the latest), in order, with the same
    /// `webhook-id`s.
    #[serde(deserialize_with = "whole")]
    #[schema(minimum = 0)]
    pub after: i64,
}

/// A JSON integer, written as one (`7`) or as a number with no fraction
/// (`7.0`: JSON Schema's `integer` admits both).
fn integer(n: &serde_json::Number) -> Option<i64> {
    n.as_i64().or_else(|| {
        n.as_f64()
            .filter(|f| f.fract() == 0.0 && f.abs() < 9.0e15)
            .map(|f| f as i64)
    })
}

fn not_integer<E: serde::de::Error>(n: &serde_json::Number) -> E {
    E::custom(format!("{n} is not an integer"))
}

fn whole<'de, D: serde::Deserializer<'de>>(d: D) -> Result<i64, D::Error> {
    let n = serde_json::Number::deserialize(d)?;
    integer(&n).ok_or_else(|| not_integer(&n))
}

fn whole_opt<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<i64>, D::Error> {
    Option::<serde_json::Number>::deserialize(d)?
        .map(|n| integer(&n).ok_or_else(|| not_integer(&n)))
        .transpose()
}

#[cfg(test)]
mod tests;
