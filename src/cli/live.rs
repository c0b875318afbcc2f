//! The flags of live updates (issue 47): the event stream's heartbeat and
//! poll interval, the status scan, and how webhooks are delivered (`--webhook-*`, each a
//! setting of [`crate::app::delivery::Settings`]).

use std::time::Duration;

use crate::app::delivery::Settings;
use crate::domain::webhooks::Retry;

/// The live updates' flags.
#[derive(Debug, clap::Args)]
pub struct LiveArgs {
    /// Seconds between heartbeat comments on `GET /v1/events` while nothing
    /// happens.
    #[arg(long, env = "ACCELCAL_EVENTS_HEARTBEAT", default_value_t = 15)]
    pub events_heartbeat: u64,
    /// Milliseconds between a replica's looks for new events in the audit
    /// trail (while anyone listens to `GET /v1/events`, and for webhooks'
    /// due deliveries).
    #[arg(long, env = "ACCELCAL_EVENTS_POLL_MS", default_value_t = 200)]
    pub events_poll_ms: u64,
    /// Seconds between a replica's looks for sensors whose status changed
    /// by the clock (due soon, overdue), each announced once as an event.
    #[arg(long, env = "ACCELCAL_STATUS_SCAN", default_value_t = 60.0)]
    pub status_scan: f64,
    /// Seconds before a failed webhook delivery is tried again the first
    /// time; the delay doubles with each failure (±20 % jitter).
    #[arg(long, env = "ACCELCAL_WEBHOOK_RETRY_BASE", default_value_t = 5.0)]
    pub webhook_retry_base: f64,
    /// Seconds between webhook retries at most.
    #[arg(long, env = "ACCELCAL_WEBHOOK_RETRY_CAP", default_value_t = 3600.0)]
    pub webhook_retry_cap: f64,
    /// Seconds after its act an event is given up by an endpoint that keeps
    /// failing (logged `abandoned`; `POST …/redeliver` sends it again).
    #[arg(long, env = "ACCELCAL_WEBHOOK_MAX_AGE", default_value_t = 3.0 * 86400.0)]
    pub webhook_max_age: f64,
    /// Seconds a webhook receiver has to answer an attempt.
    #[arg(long, env = "ACCELCAL_WEBHOOK_TIMEOUT", default_value_t = 10.0)]
    pub webhook_timeout: f64,
    /// Allow webhook targets on loopback and private addresses (refused by
    /// default, at registration and at every delivery).
    #[arg(long, env = "ACCELCAL_WEBHOOK_ALLOW_PRIVATE")]
    pub webhook_allow_private: bool,
}

impl LiveArgs {
    /// The heartbeat interval (at least a second).
    pub fn heartbeat(&self) -> Duration {
        Duration::from_secs(self.events_heartbeat.max(1))
    }

    /// The poll interval (at least 10 ms).
    pub fn poll(&self) -> Duration {
        Duration::from_millis(self.events_poll_ms.max(10))
    }

    /// The status scan's interval, checked.
    pub fn status_scan(&self) -> anyhow::Result<Duration> {
        seconds("--status-scan", self.status_scan)
    }

    /// The webhooks' settings, each checked.
    pub fn webhooks(&self) -> anyhow::Result<Settings> {
        Ok(Settings {
            retry: Retry {
                base: seconds("--webhook-retry-base", self.webhook_retry_base)?,
                cap: seconds("--webhook-retry-cap", self.webhook_retry_cap)?,
                max_age: seconds("--webhook-max-age", self.webhook_max_age)?,
            },
            timeout: seconds("--webhook-timeout", self.webhook_timeout)?,
            allow_private: self.webhook_allow_private,
            poll: self.poll(),
        })
    }
}

/// A flag's seconds as a duration: positive and finite, at most a year.
fn seconds(flag: &str, s: f64) -> anyhow::Result<Duration> {
    if s.is_finite() && s > 0.0 && s <= 366.0 * 86400.0 {
        Ok(Duration::from_secs_f64(s))
    } else {
        anyhow::bail!("{flag} {s}: seconds, more than 0 and at most a year")
    }
}
