//! The `accelcal submit` client: uploads a submission file, safely retried.
//!
//! The request carries an `Idempotency-Key` derived from the file's content
//! (`SHA-256`), so however often an upload is retried — after a timeout, a
//! dropped connection or a 503 — the server stores it at most once and
//! answers every retry with the original result. Transient failures
//! (408, 409 in flight, 429, 502, 503, 504, and a connection lost or timed
//! out) are retried with exponential backoff, honouring `Retry-After`. A
//! connection refused (or a host not found) before any attempt reached the
//! server fails at once, saying so: nothing is listening there, and waiting
//! will not change that; once the server has answered, a refusal is a
//! restart, and is retried.

use std::fmt;
use std::sync::Arc;
use std::time::Duration;

use reqwest::StatusCode;
use sha2::{Digest, Sha256};

/// One retry about to happen: which attempt failed, why, and the wait.
#[derive(Clone, Debug)]
pub struct Retry {
    /// The attempt that failed (1 for the first).
    pub attempt: u32,
    /// The status answered, or the connection error.
    pub reason: String,
    /// How long the client waits before the next attempt.
    pub wait: Duration,
}

/// Told of every retry (`accelcal submit` prints it).
pub type OnRetry = Arc<dyn Fn(&Retry) + Send + Sync>;

/// What to upload and where.
#[derive(Clone)]
pub struct Upload {
    /// Base URL of the service (`http://127.0.0.1:8080`).
    pub url: String,
    /// Bearer token.
    pub token: String,
    /// The body.
    pub body: Vec<u8>,
    /// `application/json` or `text/csv`.
    pub content_type: &'static str,
    /// Attempts in all (at least 1).
    pub attempts: u32,
    /// First backoff delay; doubles each retry.
    pub backoff: Duration,
    /// Told of every retry, if set.
    pub on_retry: Option<OnRetry>,
}

impl fmt::Debug for Upload {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Upload")
            .field("url", &self.url)
            .field("bytes", &self.body.len())
            .field("content_type", &self.content_type)
            .field("attempts", &self.attempts)
            .finish_non_exhaustive()
    }
}

/// The server's final answer.
#[derive(Clone, Debug)]
pub struct Answer {
    /// HTTP status.
    pub status: StatusCode,
    /// Body text.
    pub body: String,
    /// Attempts made.
    pub attempts: u32,
}

/// The idempotency key of a body: `sha256-<hex>` of its bytes.
pub fn idempotency_key(body: &[u8]) -> String {
    format!("sha256-{}", hex::encode(Sha256::digest(body)))
}

/// The innermost cause of a request error (`Connection refused (os error
/// 111)`), not reqwest's wrapper text.
fn cause(e: &reqwest::Error) -> String {
    let mut inner: &dyn std::error::Error = e;
    while let Some(next) = inner.source() {
        inner = next;
    }
    inner.to_string()
}

fn transient(status: StatusCode) -> bool {
    matches!(status.as_u16(), 408 | 409 | 429 | 502 | 503 | 504)
}

/// Uploads with retries; errors only when no HTTP answer was ever received.
pub async fn submit(u: &Upload) -> anyhow::Result<Answer> {
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(120))
        .connect_timeout(Duration::from_secs(10))
        .build()?;
    let url = format!("{}/v1/calibrations", u.url.trim_end_matches('/'));
    let key = idempotency_key(&u.body);
    let mut delay = u.backoff;
    let mut attempt = 0;
    // Whether any attempt got an HTTP answer.
    let mut reached = false;
    loop {
        attempt += 1;
        let sent = client
            .post(&url)
            .bearer_auth(&u.token)
            .header("content-type", u.content_type)
            .header("idempotency-key", &key)
            .body(u.body.clone())
            .send()
            .await;
        let (wait, reason) = match sent {
            Ok(res) if transient(res.status()) && attempt < u.attempts => {
                let after = res
                    .headers()
                    .get("retry-after")
                    .and_then(|v| v.to_str().ok())
                    .and_then(|v| v.parse::<u64>().ok())
                    .map(|s| Duration::from_secs(s.min(60)));
                (after.unwrap_or(delay).max(delay), res.status().to_string())
            }
            Ok(res) => {
                let status = res.status();
                let body = res.text().await.unwrap_or_default();
                return Ok(Answer {
                    status,
                    body,
                    attempts: attempt,
                });
            }
            Err(e) if e.is_connect() && !reached => {
                return Err(anyhow::anyhow!(
                    "cannot connect to {}: {} — is the service running there? Start it with \
                     `accelcal serve`, or give its address with --url (ACCELCAL_URL)",
                    u.url.trim_end_matches('/'),
                    cause(&e)
                ));
            }
            Err(e) if attempt < u.attempts => (delay, format!("no answer: {}", cause(&e))),
            Err(e) => {
                return Err(anyhow::anyhow!(
                    "no answer from {url} after {attempt} attempts: {}",
                    cause(&e)
                ));
            }
        };
        reached |= !reason.starts_with("no answer");
        if let Some(tell) = &u.on_retry {
            tell(&Retry {
                attempt,
                reason,
                wait,
            });
        }
        tokio::time::sleep(wait).await;
        delay = (delay * 2).min(Duration::from_secs(30));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_depends_on_content_only() {
        assert_eq!(idempotency_key(b"abc"), idempotency_key(b"abc"));
        assert_ne!(idempotency_key(b"abc"), idempotency_key(b"abd"));
        assert_eq!(
            idempotency_key(b"abc"),
            "sha256-ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
