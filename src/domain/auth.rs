//! Bearer tokens: generation, hashing, constant-time verification, roles,
//! and redaction of a token pasted where it does not belong.
//!
//! A token reads `acc_<id>_<secret>`: `id` is the token's UUID in 32 hex
//! digits (public: it names the token in `GET /v1/tokens` and logs), `secret`
//! is 256 random bits in unpadded base64url. Only `SHA-256(secret)` is
//! stored; a presented token is looked up by `id` and its secret's hash
//! compared in constant time. SHA-256 without salt or stretching is the right
//! tool for 256-bit random secrets: there is nothing to brute-force.

use std::fmt;

use base64::Engine as _;
use base64::engine::general_purpose::URL_SAFE_NO_PAD;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use subtle::ConstantTimeEq;
use uuid::Uuid;

/// What a token may do. Roles are ordered: each includes those below it.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Serialize,
    Deserialize,
    utoipa::ToSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Read everything; identify, fuse, compensate.
    Reader,
    /// Reader, plus submit calibrations.
    Station,
    /// Station, plus review: approve, reject and withdraw calibrations
    /// (issue 28), signed with the token's holder.
    Reviewer,
    /// Everything, including token management.
    Admin,
}

impl Role {
    /// The role's wire name.
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Reader => "reader",
            Role::Station => "station",
            Role::Reviewer => "reviewer",
            Role::Admin => "admin",
        }
    }

    /// Parses a wire name.
    pub fn parse(s: &str) -> Option<Role> {
        [Role::Reader, Role::Station, Role::Reviewer, Role::Admin]
            .into_iter()
            .find(|r| r.as_str() == s)
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Who is calling: the token's id (or `env-admin`), role and bound station.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Principal {
    /// Token id, or [`ENV_ADMIN`] for the configured admin token.
    pub id: String,
    /// The token's role.
    pub role: Role,
    /// The station a station token is bound to.
    pub station_id: Option<String>,
    /// The person who holds the token, if it names one.
    pub holder: Option<String>,
}

/// The principal id of the admin token given by configuration.
pub const ENV_ADMIN: &str = "env-admin";

const PREFIX: &str = "acc_";

/// A freshly generated token: the text shown once, and what is stored.
#[derive(Clone)]
pub struct NewToken {
    /// The token's id.
    pub id: Uuid,
    /// The whole token text, `acc_<id>_<secret>`.
    pub text: String,
    /// `SHA-256(secret)`.
    pub secret_hash: [u8; 32],
}

impl fmt::Debug for NewToken {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("NewToken")
            .field("id", &self.id)
            .finish_non_exhaustive()
    }
}

/// Generates a token with a 256-bit secret from the operating system's CSPRNG.
pub fn generate() -> Result<NewToken, getrandom::Error> {
    let mut secret = [0u8; 32];
    getrandom::fill(&mut secret)?;
    let secret = URL_SAFE_NO_PAD.encode(secret);
    let id = Uuid::now_v7();
    Ok(NewToken {
        id,
        text: format!("{PREFIX}{}_{secret}", id.simple()),
        secret_hash: hash(&secret),
    })
}

/// `SHA-256` of a secret (or of a whole configured token).
pub fn hash(secret: &str) -> [u8; 32] {
    Sha256::digest(secret.as_bytes()).into()
}

/// Least estimated entropy of a configured admin token, in bits.
pub const MIN_ADMIN_TOKEN_BITS: f64 = 128.0;

/// An estimate of the entropy of a configured token, in bits: its length
/// times the empirical Shannon entropy of its characters,
/// `n · Σ_c −(n_c/n) log2(n_c/n)` over the distinct characters `c` occurring
/// `n_c` times.
///
/// It is an upper bound on what a person typed (a phrase scores high for
/// its length) and close to the truth for random text: 32 random bytes in
/// base64 (44 characters) score about 200 bits, in hex (64) about 240. A
/// repeated character scores 0; the README's old example
/// `change-me-to-something-long` scores about 99.
pub fn estimated_bits(token: &str) -> f64 {
    let mut counts = std::collections::HashMap::new();
    for c in token.chars() {
        *counts.entry(c).or_insert(0usize) += 1;
    }
    let n: usize = counts.values().sum();
    if n == 0 {
        return 0.0;
    }
    let nf = n as f64;
    let per_char: f64 = counts
        .values()
        // p·log2(1/p), never −0 (a repeated character must read "0 bits").
        .map(|&k| k as f64 / nf * (nf / k as f64).log2())
        .sum();
    per_char * nf
}

/// Splits a presented token into its id and secret, if it has the form.
pub fn parse(text: &str) -> Option<(Uuid, &str)> {
    let rest = text.strip_prefix(PREFIX)?;
    let (id, secret) = rest.split_at_checked(32)?;
    let secret = secret.strip_prefix('_')?;
    if secret.len() != 43 {
        return None;
    }
    Some((Uuid::try_parse(id).ok()?, secret))
}

/// Whether `secret` hashes to `stored`, compared in constant time.
pub fn verify(secret: &str, stored: &[u8]) -> bool {
    hash(secret).ct_eq(stored).into()
}

/// Where a token's secret starts and ends in `text`, for every token pasted
/// into it (`acc_`, 32 hex digits, `_`, then the base64url secret).
fn secrets(text: &str) -> Vec<std::ops::Range<usize>> {
    let bytes = text.as_bytes();
    let mut found = Vec::new();
    let mut from = 0;
    while let Some(at) = text[from..].find(PREFIX).map(|k| from + k) {
        let id = at + PREFIX.len();
        let sep = id + 32;
        let ok = bytes.len() > sep
            && bytes[id..sep].iter().all(u8::is_ascii_hexdigit)
            && bytes[sep] == b'_';
        if !ok {
            from = id;
            continue;
        }
        let start = sep + 1;
        let end = start
            + bytes[start..]
                .iter()
                .take_while(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_'))
                .count();
        if end > start {
            found.push(start..end);
        }
        from = end;
    }
    found
}

/// Whether `text` holds something shaped like a token (with its secret).
pub fn holds_token(text: &str) -> bool {
    !secrets(text).is_empty()
}

/// `text` with the secret of every token pasted into it replaced by
/// `[redacted]`; the token's id (public) stays, so a log still says which.
pub fn redact(text: &str) -> std::borrow::Cow<'_, str> {
    let found = secrets(text);
    if found.is_empty() {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len());
    let mut last = 0;
    for r in found {
        out.push_str(&text[last..r.start]);
        out.push_str("[redacted]");
        last = r.end;
    }
    out.push_str(&text[last..]);
    std::borrow::Cow::Owned(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate against a computation written out by hand.
    #[test]
    fn entropy_is_length_times_shannon_entropy_of_the_characters() {
        assert_eq!(estimated_bits(""), 0.0);
        assert_eq!(estimated_bits(&"a".repeat(16)), 0.0);
        assert!(estimated_bits(&"a".repeat(16)).is_sign_positive());
        assert_eq!(format!("{:.0}", estimated_bits(&"a".repeat(16))), "0");
        // "abab": two characters at 1/2 each, 1 bit each, 4 characters.
        assert!((estimated_bits("abab") - 4.0).abs() < 1e-12);
        // "aab": -(2/3 log2 2/3 + 1/3 log2 1/3) = 0.918 295 834 bits, 3 characters.
        assert!((estimated_bits("aab") - 3.0 * 0.918_295_834_054_489_6).abs() < 1e-12);
        let example = estimated_bits("change-me-to-something-long");
        assert!(example < MIN_ADMIN_TOKEN_BITS, "{example}");
        assert!(estimated_bits("test-admin-token-0123456789") < MIN_ADMIN_TOKEN_BITS);
        // 32 random bytes, base64: what the README tells operators to make.
        let random = "q3Zb1tq0V8yHhJ+f0KXo4m9u2Rj7cLwAeGsTnP5dXiE=";
        assert!(estimated_bits(random) > MIN_ADMIN_TOKEN_BITS);
    }

    #[test]
    fn generated_tokens_parse_and_verify() {
        let t = generate().unwrap();
        let (id, secret) = parse(&t.text).unwrap();
        assert_eq!(id, t.id);
        assert!(verify(secret, &t.secret_hash));
        assert!(!verify("x", &t.secret_hash));
        let other = generate().unwrap();
        assert_ne!(t.text, other.text);
        assert_eq!(
            format!("{t:?}"),
            format!("NewToken {{ id: {}, .. }}", t.id),
            "Debug shows the id, never the secret"
        );
    }

    #[test]
    fn malformed_tokens_do_not_parse() {
        for bad in [
            "",
            "acc_",
            "acc_zz",
            "Bearer x",
            "acc_0123456789abcdef0123456789abcdef_short",
        ] {
            assert!(parse(bad).is_none(), "{bad}");
        }
    }

    #[test]
    fn pasted_tokens_are_redacted_wherever_they_appear() {
        let t = generate().unwrap();
        let secret = parse(&t.text).unwrap().1.to_owned();
        for text in [
            t.text.clone(),
            format!("/v1/tokens/{}", t.text),
            format!("a{}b {} c", t.text, t.text),
        ] {
            let r = redact(&text);
            assert!(!r.contains(&secret), "{r}");
            assert!(r.contains(&t.id.simple().to_string()), "the id stays: {r}");
            assert!(holds_token(&text));
        }
        assert_eq!(
            redact(&format!("token={} end", t.text)),
            format!("token=acc_{}_[redacted] end", t.id.simple()),
            "exactly the secret is replaced, not the `_` before it"
        );
        assert_eq!(redact("acc_nothex_x"), "acc_nothex_x");
        // An id at the very end, with no `_` or secret after it: nothing to
        // redact (and nothing read past the text's end).
        let bare_id = format!("see acc_{}", t.id.simple());
        assert_eq!(redact(&bare_id), bare_id);
        assert!(!holds_token(&bare_id));
        // An id and its `_` with no secret after them: nothing to redact.
        let no_secret = format!("see acc_{}_ (cut)", t.id.simple());
        assert_eq!(redact(&no_secret), no_secret);
        assert!(!holds_token(&no_secret));
        assert!(!holds_token("01a200f3-0000-7000-8000-000000000000"));
    }

    #[test]
    fn roles_are_ordered() {
        assert!(Role::Admin > Role::Reviewer && Role::Reviewer > Role::Station);
        assert!(Role::Station > Role::Reader);
        assert_eq!(Role::parse("reviewer"), Some(Role::Reviewer));
        assert_eq!(Role::parse("station"), Some(Role::Station));
        assert_eq!(Role::parse("root"), None);
    }
}
