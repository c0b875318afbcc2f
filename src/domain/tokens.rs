//! Token issuance rules, shared by `POST /v1/tokens` and `accelcal token
//! create`: what may be asked for, and the record a new token leaves.

use serde::{Deserialize, Serialize};
use uuid::Uuid;

use super::auth::{self, Role};
use super::field::{Errors, Invalid, Loc};
use super::limits::{MAX_HOLDER_CHARS, MAX_ID_CHARS, MAX_LABEL_CHARS};
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// The body of a token request.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TokenRequest {
    /// What the token may do.
    pub role: Role,
    /// Binds a station token to this station: it then submits as that
    /// station only. Only a station token may be bound.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_identifier)]
    pub station_id: Option<String>,
    /// A label to recognise the token by (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub label: Option<String>,
    /// The name of the person who holds the token (one line, at most 128
    /// characters): what their signatures print.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_holder)]
    pub holder: Option<String>,
}

impl TokenRequest {
    /// Checks the request's values; every problem is reported.
    pub fn check(self) -> Result<TokenRequest, Invalid> {
        let mut errors = Errors::default();
        let root = Loc::Root;
        if let Some(s) = &self.station_id {
            if let Err(why) = check_str(s, MAX_ID_CHARS, Chars::Identifier) {
                errors.add(root.key("station_id"), why);
            } else if self.role != Role::Station {
                errors.add(
                    root.key("station_id"),
                    "only a station token can be bound to a station",
                );
            }
        }
        if let Some(l) = &self.label
            && let Err(why) = check_str(l, MAX_LABEL_CHARS, Chars::Line)
        {
            errors.add(root.key("label"), why);
        }
        if let Some(h) = &self.holder
            && let Err(why) = check_str(h, MAX_HOLDER_CHARS, Chars::Line)
        {
            errors.add(root.key("holder"), why);
        }
        errors.finish(|| self)
    }
}

/// A stored token (never its secret).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TokenRecord {
    /// Token id (public; part of the token text).
    pub id: Uuid,
    /// `SHA-256(secret)`.
    pub secret_hash: Vec<u8>,
    /// Role.
    pub role: Role,
    /// Bound station.
    pub station_id: Option<String>,
    /// Free-text label.
    pub label: Option<String>,
    /// The person who holds it.
    pub holder: Option<String>,
    /// Creation time.
    pub created_at: Timestamp,
    /// Revocation time, if revoked.
    pub revoked_at: Option<Timestamp>,
}

/// A token as listed: everything but the hash of its secret.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
#[schema(as = Token)]
pub struct TokenView {
    /// Token id.
    pub id: Uuid,
    /// Role.
    pub role: Role,
    /// The station a station token is bound to.
    pub station_id: Option<String>,
    /// Label.
    pub label: Option<String>,
    /// The person who holds it.
    pub holder: Option<String>,
    /// When it was created.
    pub created_at: Timestamp,
    /// When it was revoked, if it was.
    pub revoked_at: Option<Timestamp>,
}

impl From<&TokenRecord> for TokenView {
    fn from(t: &TokenRecord) -> Self {
        TokenView {
            id: t.id,
            role: t.role,
            station_id: t.station_id.clone(),
            label: t.label.clone(),
            holder: t.holder.clone(),
            created_at: t.created_at,
            revoked_at: t.revoked_at,
        }
    }
}

/// A new token: what is stored, and the secret text shown only once.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct CreatedToken {
    /// Token id.
    pub id: Uuid,
    /// The whole token (`acc_<id>_<secret>`): shown only in this answer.
    pub token: String,
    /// Role.
    pub role: Role,
    /// The bound station.
    pub station_id: Option<String>,
    /// Label.
    pub label: Option<String>,
    /// The person who holds it.
    pub holder: Option<String>,
    /// When it was created.
    pub created_at: Timestamp,
}

/// Generates a token for a checked request: the record to store and the
/// answer that shows its secret.
pub fn issue(
    req: TokenRequest,
    now: Timestamp,
) -> Result<(TokenRecord, CreatedToken), getrandom::Error> {
    let new = auth::generate()?;
    let record = TokenRecord {
        id: new.id,
        secret_hash: new.secret_hash.to_vec(),
        role: req.role,
        station_id: req.station_id,
        label: req.label,
        holder: req.holder,
        created_at: now,
        revoked_at: None,
    };
    let created = CreatedToken {
        id: record.id,
        token: new.text,
        role: record.role,
        station_id: record.station_id.clone(),
        label: record.label.clone(),
        holder: record.holder.clone(),
        created_at: now,
    };
    Ok((record, created))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::typed::from_json;

    fn check(body: &str) -> Result<TokenRequest, Vec<String>> {
        from_json::<TokenRequest>(body.as_bytes())
            .map_err(|e| match e {
                crate::domain::typed::BodyError::Invalid(i) => i,
                other => panic!("{other:?}"),
            })
            .and_then(TokenRequest::check)
            .map_err(|i| i.errors.into_iter().map(|e| e.pointer).collect())
    }

    #[test]
    fn only_station_tokens_bind_a_station() {
        assert!(check(r#"{"role": "station", "station_id": "LAB-1"}"#).is_ok());
        assert_eq!(
            check(r#"{"role": "reader", "station_id": "LAB-1"}"#).unwrap_err(),
            ["/station_id"]
        );
        assert_eq!(
            check(r#"{"role": "station", "station_id": "bad id", "label": "a\u0007"}"#)
                .unwrap_err(),
            ["/station_id", "/label"]
        );
        assert_eq!(check(r#"{"role": "root"}"#).unwrap_err(), ["/role"]);
        // A holder names a person on one line, of any role.
        let ok = check(r#"{"role": "reviewer", "holder": "Ana Ruiz-Pérez"}"#).unwrap();
        assert_eq!(
            (ok.role, ok.holder.as_deref()),
            (Role::Reviewer, Some("Ana Ruiz-Pérez"))
        );
        let long = format!(r#"{{"role": "reader", "holder": "{}"}}"#, "x".repeat(129));
        assert_eq!(check(&long).unwrap_err(), ["/holder"]);
        assert_eq!(
            check(r#"{"role": "reader", "holder": "a\nb"}"#).unwrap_err(),
            ["/holder"]
        );
        assert_eq!(check(r#"{}"#).unwrap_err(), ["/role"]);
    }

    #[test]
    fn issued_tokens_verify_and_show_their_secret_once() {
        let now = Timestamp::parse("2026-11-22T00:00:00Z").unwrap();
        let req = check(r#"{"role": "admin", "label": "first"}"#).unwrap();
        let (record, created) = issue(req, now).unwrap();
        let (id, secret) = auth::parse(&created.token).unwrap();
        assert_eq!(id, record.id);
        assert!(auth::verify(secret, &record.secret_hash));
        assert_eq!((record.role, record.created_at), (Role::Admin, now));
    }
}
