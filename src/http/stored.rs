//! What every storing request shares: its `Idempotency-Key` read, and the
//! 201 answer for the calibration it stored (a submission, a triad, a
//! correction), marked when it replays an earlier request's.

use axum::http::{HeaderMap, HeaderName, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};
use uuid::Uuid;

use super::body::Body;
use super::problem::Problem;
use crate::app::Submitted;
use crate::domain::auth::Principal;
use crate::domain::submission::Media;
use crate::store::IdempotencyKey;

/// The `Idempotency-Key` request header.
pub static IDEMPOTENCY_KEY: HeaderName = HeaderName::from_static("idempotency-key");

/// The idempotency key of a request, if it sent one: 1–255 visible ASCII
/// characters, scoped to the principal, fingerprinted with the body and,
/// for a kind other than a single axis, with `kind` (what the body is
/// submitted as, and how it is fitted).
pub fn idempotency_key(
    headers: &HeaderMap,
    principal: &Principal,
    body: &Body,
    kind: Option<&str>,
) -> Result<Option<IdempotencyKey>, Problem> {
    let mut values = headers.get_all(&IDEMPOTENCY_KEY).iter();
    let Some(value) = values.next() else {
        return Ok(None);
    };
    if values.next().is_some() {
        return Err(Problem::bad_parameter(
            "Idempotency-Key",
            "is sent more than once",
        ));
    }
    let key = value
        .to_str()
        .ok()
        .filter(|k| (1..=255).contains(&k.len()) && k.bytes().all(|b| (0x21..=0x7e).contains(&b)))
        .ok_or_else(|| {
            Problem::bad_parameter(
                "Idempotency-Key",
                "must be 1 to 255 visible ASCII characters",
            )
        })?;
    let mut hash = Sha256::new();
    // What the body is submitted as, unless a single axis (whose hash is
    // as it always was): the same key and bytes sent as another kind, or
    // fitted otherwise, are another request.
    if let Some(kind) = kind {
        hash.update(kind.as_bytes());
        hash.update(b"\n");
    }
    hash.update(match body.media {
        Media::Json => b"json\n".as_slice(),
        Media::Csv => b"csv\n".as_slice(),
    });
    hash.update(&body.bytes);
    Ok(Some(IdempotencyKey {
        principal: principal.id.clone(),
        key: key.to_owned(),
        request_hash: hash.finalize().into(),
        holder: Uuid::now_v7(),
    }))
}

/// The 201 answer for a stored calibration.
pub fn created(s: Submitted) -> Response {
    let location = HeaderValue::from_str(&format!("/v1/calibrations/{}", s.id))
        .unwrap_or(HeaderValue::from_static("/v1/calibrations"));
    let mut res = (
        StatusCode::CREATED,
        [
            (header::LOCATION, location),
            (
                header::CONTENT_TYPE,
                HeaderValue::from_static("application/json"),
            ),
        ],
        s.result,
    )
        .into_response();
    if s.replayed {
        res.headers_mut().insert(
            HeaderName::from_static("idempotent-replayed"),
            HeaderValue::from_static("true"),
        );
    }
    res
}
