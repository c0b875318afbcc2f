//! Request extractors: the caller's [`Principal`], a bounded request [`Body`],
//! and strict query parameters.

use std::collections::HashMap;

use axum::body::Bytes;
use axum::extract::{FromRequest, FromRequestParts, Request};
use axum::http::header;
use axum::http::request::Parts;
use http_body_util::{BodyExt, LengthLimitError, Limited};
use serde_json::Value;
use subtle::ConstantTimeEq;

use super::AppState;
use super::problem::Problem;
use crate::auth::{self, ENV_ADMIN, Principal, Role};
use crate::input::{csv, strict};

impl FromRequestParts<AppState> for Principal {
    type Rejection = Problem;

    async fn from_request_parts(parts: &mut Parts, state: &AppState) -> Result<Self, Problem> {
        let value = parts
            .headers
            .get(header::AUTHORIZATION)
            .ok_or_else(|| Problem::unauthorized("send `Authorization: Bearer <token>`"))?;
        let text = value
            .to_str()
            .ok()
            .and_then(|v| v.split_once(' '))
            .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
            .map(|(_, token)| token.trim())
            .ok_or_else(|| {
                Problem::unauthorized("the Authorization header must read `Bearer <token>`")
            })?;
        if let Some(admin) = &state.admin_token_hash
            && bool::from(auth::hash(text).ct_eq(admin))
        {
            return Ok(Principal {
                id: ENV_ADMIN.to_owned(),
                role: Role::Admin,
                station_id: None,
            });
        }
        let invalid = || Problem::unauthorized("the token is not valid");
        let (id, secret) = auth::parse(text).ok_or_else(invalid)?;
        let record = state.store.token(id).await?.ok_or_else(invalid)?;
        if !auth::verify(secret, &record.secret_hash) {
            return Err(invalid());
        }
        if record.revoked_at.is_some() {
            return Err(Problem::unauthorized("the token has been revoked"));
        }
        Ok(Principal {
            id: record.id.simple().to_string(),
            role: record.role,
            station_id: record.station_id,
        })
    }
}

impl Principal {
    /// Refuses (403) a principal whose role is below `role`.
    pub fn require(&self, role: Role) -> Result<(), Problem> {
        if self.role >= role {
            Ok(())
        } else {
            Err(Problem::forbidden(format!(
                "this operation needs a {role} token; this token's role is {}",
                self.role
            )))
        }
    }
}

/// The media types accelcal reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Media {
    /// `application/json`.
    Json,
    /// `text/csv` (submissions only).
    Csv,
}

/// A request body read whole, within the size and time limits.
#[derive(Debug)]
pub struct Body {
    /// Its media type.
    pub media: Media,
    /// Its bytes.
    pub bytes: Bytes,
    /// The `Content-Type` as sent (stored with submissions).
    pub content_type: String,
}

fn media(content_type: &str) -> Result<Media, Problem> {
    let mut parts = content_type.split(';').map(str::trim);
    let essence = parts.next().unwrap_or_default().to_ascii_lowercase();
    for param in parts.filter(|p| !p.is_empty()) {
        let (name, value) = param.split_once('=').unwrap_or((param, ""));
        let value = value.trim_matches('"');
        if !(name.eq_ignore_ascii_case("charset") && value.eq_ignore_ascii_case("utf-8")) {
            return Err(Problem::unsupported_media(format!(
                "unsupported media type parameter `{param}`; bodies are UTF-8"
            )));
        }
    }
    match essence.as_str() {
        "application/json" => Ok(Media::Json),
        "text/csv" => Ok(Media::Csv),
        _ => Err(Problem::unsupported_media(format!(
            "Content-Type `{content_type}` is not accepted; send application/json (or text/csv for submissions)"
        ))),
    }
}

impl FromRequest<AppState> for Body {
    type Rejection = Problem;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, Problem> {
        let limit = state.limits.max_body_bytes;
        let content_type = req
            .headers()
            .get(header::CONTENT_TYPE)
            .ok_or_else(|| {
                Problem::unsupported_media("a Content-Type header is required (application/json)")
            })?
            .to_str()
            .map_err(|_| Problem::unsupported_media("the Content-Type header is not ASCII"))?
            .to_owned();
        let media = media(&content_type)?;
        let declared = req
            .headers()
            .get(header::CONTENT_LENGTH)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.parse::<u64>().ok());
        if declared.is_some_and(|n| n > limit as u64) {
            return Err(Problem::too_large(limit));
        }
        let read = Limited::new(req.into_body(), limit).collect();
        let collected = tokio::time::timeout(state.limits.body_timeout, read)
            .await
            .map_err(|_| {
                Problem::request_timeout(format!(
                    "the body was not received within {} s",
                    state.limits.body_timeout.as_secs()
                ))
            })?;
        let bytes = match collected {
            Ok(c) => c.to_bytes(),
            Err(e) if e.downcast_ref::<LengthLimitError>().is_some() => {
                return Err(Problem::too_large(limit));
            }
            Err(e) => {
                return Err(Problem::bad_request(format!(
                    "the body could not be read: {e}"
                )));
            }
        };
        Ok(Body {
            media,
            bytes,
            content_type,
        })
    }
}

impl Body {
    /// The body as JSON (refusing CSV with 415).
    pub fn json(&self) -> Result<Value, Problem> {
        if self.media != Media::Json {
            return Err(Problem::unsupported_media(
                "this operation accepts application/json only",
            ));
        }
        parse_json(&self.bytes)
    }

    /// The body as a JSON submission, converting CSV.
    pub fn submission(&self) -> Result<Value, Problem> {
        submission_value(self.media, &self.bytes)
    }
}

/// A submission body of either media type as its JSON form.
pub fn submission_value(media: Media, bytes: &[u8]) -> Result<Value, Problem> {
    match media {
        Media::Json => parse_json(bytes),
        Media::Csv => {
            let text = std::str::from_utf8(bytes)
                .map_err(|e| Problem::bad_request(format!("the CSV body is not UTF-8: {e}")))?;
            csv::to_json(text).map_err(Problem::validation)
        }
    }
}

fn parse_json(bytes: &[u8]) -> Result<Value, Problem> {
    strict::parse(bytes).map_err(|e| match e {
        strict::JsonError::Syntax(m) => {
            Problem::bad_request(format!("the body is not valid JSON: {m}"))
        }
        strict::JsonError::Structure(m) => Problem::validation(vec![crate::input::FieldError {
            pointer: String::new(),
            detail: m,
        }]),
    })
}

/// Query parameters, refusing unknown and repeated names.
pub struct Params(HashMap<String, String>);

impl Params {
    /// Parses a raw query string against the allowed names.
    pub fn parse(query: Option<&str>, allowed: &[&str]) -> Result<Self, Problem> {
        let mut map = HashMap::new();
        for (k, v) in form_urlencoded::parse(query.unwrap_or_default().as_bytes()) {
            if !allowed.contains(&k.as_ref()) {
                return Err(Problem::bad_parameter(
                    &k,
                    format!("is not known here; expected one of: {}", allowed.join(", ")),
                ));
            }
            if map.insert(k.to_string(), v.into_owned()).is_some() {
                return Err(Problem::bad_parameter(&k, "is given more than once"));
            }
        }
        Ok(Params(map))
    }

    /// A parameter's value.
    pub fn get(&self, name: &str) -> Option<&str> {
        self.0.get(name).map(String::as_str)
    }

    /// The page size: `limit`, 1 to [`MAX_PAGE`], default [`DEFAULT_PAGE`].
    pub fn limit(&self) -> Result<usize, Problem> {
        match self.get("limit") {
            None => Ok(DEFAULT_PAGE),
            Some(s) => s
                .parse::<usize>()
                .ok()
                .filter(|n| (1..=MAX_PAGE).contains(n))
                .ok_or_else(|| {
                    Problem::bad_parameter(
                        "limit",
                        format!("must be an integer from 1 to {MAX_PAGE}"),
                    )
                }),
        }
    }
}

/// Default page size.
pub const DEFAULT_PAGE: usize = 50;
/// Largest page size.
pub const MAX_PAGE: usize = 500;
