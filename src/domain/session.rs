//! Sessions of the web pages: what a sign-in leaves, and the secrets it
//! hands out.
//!
//! Signing in with a token opens a session: the browser keeps a random
//! 256-bit session id in an `HttpOnly` cookie, the store keeps only its
//! SHA-256 ([`SessionRecord::id_hash`]), the token it was opened with and the
//! hash of that token's secret — so a revoked token (or a changed configured
//! admin token) ends the session at once — and a CSRF token that every form
//! of the session must send back. Sessions end at `expires_at` (a fixed
//! lifetime from sign-in) or at sign-out.

use base64::Engine as _;
use base64::engine::general_purpose::URL_SAFE_NO_PAD;
use subtle::ConstantTimeEq;

use super::auth;
use super::timestamp::Timestamp;

/// A stored session.
#[derive(Clone, PartialEq, Eq)]
pub struct SessionRecord {
    /// `SHA-256` of the session id the cookie holds.
    pub id_hash: [u8; 32],
    /// The principal id of the token it was opened with (a token id, or
    /// [`auth::ENV_ADMIN`]).
    pub principal: String,
    /// `SHA-256` of that token's secret (of the whole configured admin token).
    pub credential_hash: [u8; 32],
    /// The token every form of this session must carry.
    pub csrf: String,
    /// When it was opened.
    pub created_at: Timestamp,
    /// When it ends.
    pub expires_at: Timestamp,
}

impl std::fmt::Debug for SessionRecord {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SessionRecord")
            .field("principal", &self.principal)
            .field("expires_at", &self.expires_at)
            .finish_non_exhaustive()
    }
}

/// A random 256-bit secret in unpadded base64url (43 characters), from the
/// operating system's CSPRNG.
pub fn secret() -> Result<String, getrandom::Error> {
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes)?;
    Ok(URL_SAFE_NO_PAD.encode(bytes))
}

/// A new session for `principal`, whose token's secret hashes to
/// `credential_hash`, lasting `ttl_seconds` from `now`: the record to store
/// and the session id for the cookie.
pub fn open(
    principal: String,
    credential_hash: [u8; 32],
    now: Timestamp,
    ttl_seconds: i64,
) -> Result<(SessionRecord, String), getrandom::Error> {
    let id = secret()?;
    let record = SessionRecord {
        id_hash: auth::hash(&id),
        principal,
        credential_hash,
        csrf: secret()?,
        created_at: now,
        expires_at: now.plus_seconds(ttl_seconds),
    };
    Ok((record, id))
}

/// Whether two secrets are equal, compared in constant time (for CSRF
/// tokens; lengths are not secret).
pub fn same_secret(a: &str, b: &str) -> bool {
    a.len() == b.len() && bool::from(a.as_bytes().ct_eq(b.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_session_keeps_only_the_hash_of_its_id() {
        let now = Timestamp::parse("2026-11-22T00:00:00Z").unwrap();
        let (record, id) = open("p".into(), [7; 32], now, 3600).unwrap();
        assert_eq!(id.len(), 43);
        assert_eq!(record.id_hash, auth::hash(&id));
        assert_ne!(record.csrf, id);
        assert_eq!(record.expires_at, now.plus_seconds(3600));
        let (other, other_id) = open("p".into(), [7; 32], now, 3600).unwrap();
        assert_ne!(other_id, id);
        assert_ne!(other.csrf, record.csrf);
        let debug = format!("{record:?}");
        assert!(!debug.contains(&record.csrf), "{debug}");
        assert!(
            debug.starts_with(r#"SessionRecord { principal: "p", expires_at: "#),
            "{debug}"
        );
    }

    #[test]
    fn secrets_compare_equal_only_when_equal() {
        assert!(same_secret("abc", "abc"));
        assert!(!same_secret("abc", "abd"));
        assert!(!same_secret("abc", "ab"));
        assert!(!same_secret("", "a"));
    }
}
