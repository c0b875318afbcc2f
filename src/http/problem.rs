//! RFC 9457 problem details: the one error shape of every 4xx and 5xx.
//!
//! ```json
//! {"type": "urn:accelcal:problem:validation", "title": "Invalid request content",
//!  "status": 422, "detail": "2 problems in the request body",
//!  "errors": [{"pointer": "/runs/2/readings/1", "detail": "must not be empty"}],
//!  "request_id": "…"}
//! ```
//!
//! Handlers return [`Problem`]; the response carries a copy in its extensions
//! so that the outermost middleware can add the `request_id`
//! (see [`super::stack::finalize`]). Validation lists at most a hundred
//! field errors and counts the rest in `errors_omitted`; whatever a problem
//! repeats of the client's input is cut short and has any pasted token's
//! secret redacted ([`crate::domain::text::echo`]).

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use crate::domain::field::{FieldError, Invalid, Loc};
use crate::domain::submission::Refused;
use crate::domain::text::echo;
use crate::domain::typed::BodyError;
use crate::store::StoreError;

/// The media type of problem documents.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// The kinds of problem accelcal answers: each a `type`
/// (`urn:accelcal:problem:<name>`), a title and a usual status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// 400: not JSON, a malformed query parameter or header, an unreadable body.
    Malformed,
    /// 422: well-formed, but fields are wrong or the test cannot be calibrated.
    Validation,
    /// 401: no valid token.
    Unauthorized,
    /// 403: the token's role or station does not allow this.
    Forbidden,
    /// 404: no such resource.
    NotFound,
    /// 405: the resource does not support the method.
    MethodNotAllowed,
    /// 408: the body was not received in time.
    Timeout,
    /// 409: a request with the same Idempotency-Key is still being processed.
    InFlight,
    /// 409: coefficients asked for with `require=usable` are not usable.
    NotUsable,
    /// 409: the calibration's state does not allow the act.
    StateConflict,
    /// 409: the records lack what the document asked for needs (a Digital
    /// Calibration Certificate without the laboratory's country or the
    /// item's customer).
    Incomplete,
    /// 409: the request is for a single-axis calibration and this is a
    /// triad's (or the other way round): a sensor's calibrations are all of
    /// one kind.
    WrongKind,
    /// 409: the firmware format asked for cannot carry a term of the
    /// temperature model that matters over its range (an element of `S`
    /// changing by more than its expanded uncertainty).
    NotCarried,
    /// 412: a conditional write (`If-Match`, `If-None-Match`) whose
    /// precondition does not hold: the record changed since it was read.
    PreconditionFailed,
    /// 413: the body is too large.
    TooLarge,
    /// 429: too many failed authentications from the client's address.
    TooManyRequests,
    /// 415: a Content-Type or Content-Encoding accelcal does not read.
    UnsupportedMediaType,
    /// 422: an Idempotency-Key reused with a different body.
    IdempotencyKeyReused,
    /// 501: a transfer coding accelcal does not implement.
    NotImplemented,
    /// 503: the database is unavailable or the server is at capacity.
    Unavailable,
    /// 500: a fault of accelcal's own.
    Internal,
}

impl Kind {
    /// Every kind, for documentation.
    pub const ALL: [Kind; 21] = [
        Kind::Malformed,
        Kind::Validation,
        Kind::Unauthorized,
        Kind::Forbidden,
        Kind::NotFound,
        Kind::MethodNotAllowed,
        Kind::Timeout,
        Kind::InFlight,
        Kind::NotUsable,
        Kind::StateConflict,
        Kind::Incomplete,
        Kind::WrongKind,
        Kind::NotCarried,
        Kind::PreconditionFailed,
        Kind::TooLarge,
        Kind::TooManyRequests,
        Kind::UnsupportedMediaType,
        Kind::IdempotencyKeyReused,
        Kind::NotImplemented,
        Kind::Unavailable,
        Kind::Internal,
    ];

    /// The name in the problem's `type`.
    pub const fn name(self) -> &'static str {
        match self {
            Kind::Malformed => "malformed",
            Kind::Validation => "validation",
            Kind::Unauthorized => "unauthorized",
            Kind::Forbidden => "forbidden",
            Kind::NotFound => "not-found",
            Kind::MethodNotAllowed => "method-not-allowed",
            Kind::Timeout => "timeout",
            Kind::InFlight => "in-flight",
            Kind::NotUsable => "not-usable",
            Kind::StateConflict => "state-conflict",
            Kind::Incomplete => "incomplete-record",
            Kind::WrongKind => "wrong-kind",
            Kind::NotCarried => "not-carried",
            Kind::PreconditionFailed => "precondition-failed",
            Kind::TooLarge => "too-large",
            Kind::TooManyRequests => "too-many-requests",
            Kind::UnsupportedMediaType => "unsupported-media-type",
            Kind::IdempotencyKeyReused => "idempotency-key-reused",
            Kind::NotImplemented => "not-implemented",
            Kind::Unavailable => "unavailable",
            Kind::Internal => "internal",
        }
    }

    /// The problem type's title.
    pub const fn title(self) -> &'static str {
        match self {
            Kind::Malformed => "Malformed request",
            Kind::Validation => "Invalid request content",
            Kind::Unauthorized => "Authentication required",
            Kind::Forbidden => "Not allowed",
            Kind::NotFound => "Not found",
            Kind::MethodNotAllowed => "Method not allowed",
            Kind::Timeout => "Request timeout",
            Kind::InFlight => "Request in progress",
            Kind::NotUsable => "Coefficients not usable",
            Kind::StateConflict => "Not allowed in the calibration's state",
            Kind::Incomplete => "Records incomplete for this document",
            Kind::WrongKind => "Not for this kind of calibration",
            Kind::NotCarried => "The format cannot carry the model",
            Kind::PreconditionFailed => "The record changed since it was read",
            Kind::TooLarge => "Request body too large",
            Kind::TooManyRequests => "Too many requests",
            Kind::UnsupportedMediaType => "Unsupported media type",
            Kind::IdempotencyKeyReused => "Idempotency-Key reused",
            Kind::NotImplemented => "Not implemented",
            Kind::Unavailable => "Service unavailable",
            Kind::Internal => "Internal error",
        }
    }

    /// The status it is answered with.
    pub const fn status(self) -> StatusCode {
        match self {
            Kind::Malformed => StatusCode::BAD_REQUEST,
            Kind::Validation | Kind::IdempotencyKeyReused => StatusCode::UNPROCESSABLE_ENTITY,
            Kind::Unauthorized => StatusCode::UNAUTHORIZED,
            Kind::Forbidden => StatusCode::FORBIDDEN,
            Kind::NotFound => StatusCode::NOT_FOUND,
            Kind::MethodNotAllowed => StatusCode::METHOD_NOT_ALLOWED,
            Kind::Timeout => StatusCode::REQUEST_TIMEOUT,
            Kind::InFlight
            | Kind::NotUsable
            | Kind::StateConflict
            | Kind::Incomplete
            | Kind::WrongKind
            | Kind::NotCarried => StatusCode::CONFLICT,
            Kind::PreconditionFailed => StatusCode::PRECONDITION_FAILED,
            Kind::TooLarge => StatusCode::PAYLOAD_TOO_LARGE,
            Kind::TooManyRequests => StatusCode::TOO_MANY_REQUESTS,
            Kind::UnsupportedMediaType => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            Kind::NotImplemented => StatusCode::NOT_IMPLEMENTED,
            Kind::Unavailable => StatusCode::SERVICE_UNAVAILABLE,
            Kind::Internal => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }
}

/// A problem document with its HTTP status and headers.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// HTTP status (usually the kind's).
    pub status: StatusCode,
    /// The problem type.
    pub kind: Kind,
    /// What happened in this occurrence.
    pub detail: String,
    /// `Retry-After` seconds, for retryable problems.
    pub retry_after: Option<u32>,
    /// Field errors and the parameter at fault, when there are any.
    pub fields: Option<Box<Fields>>,
}

/// The parts of a problem only some problems have.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Fields {
    /// Field-level problems, for validation failures (at most a hundred).
    pub errors: Vec<FieldError>,
    /// Field-level problems found beyond those listed.
    pub errors_omitted: usize,
    /// The query parameter or header at fault, for malformed parameters.
    pub parameter: Option<String>,
}

/// The problem document on the wire.
#[derive(Serialize, ToSchema)]
#[schema(as = Problem)]
pub struct ProblemBody<'a> {
    /// `urn:accelcal:problem:<kind>`: the problem type.
    #[serde(rename = "type")]
    #[schema(example = "urn:accelcal:problem:validation")]
    pub kind: String,
    /// The problem type's title.
    pub title: &'a str,
    /// The HTTP status.
    #[schema(minimum = 400, maximum = 599)]
    pub status: u16,
    /// What happened in this occurrence.
    pub detail: &'a str,
    /// For 422: what is wrong where, as RFC 6901 pointers into the body.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub errors: &'a [FieldError],
    /// For 422: how many more problems were found than are listed.
    #[serde(skip_serializing_if = "is_zero")]
    #[schema(minimum = 1)]
    pub errors_omitted: usize,
    /// For 400: the query parameter or header at fault.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parameter: Option<&'a str>,
    /// The request's id (also in the `x-request-id` header and the log).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request_id: Option<&'a str>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Problem {
    /// A problem of `kind`, answered with the kind's status.
    pub fn new(kind: Kind, detail: impl Into<String>) -> Self {
        Problem {
            status: kind.status(),
            kind,
            detail: detail.into(),
            retry_after: None,
            fields: None,
        }
    }

    /// The same problem answered with another status (framework errors).
    pub fn with_status(self, status: StatusCode) -> Self {
        Problem { status, ..self }
    }

    /// The same problem with `Retry-After`.
    pub fn retry_after(self, seconds: u32) -> Self {
        Problem {
            retry_after: Some(seconds),
            ..self
        }
    }

    /// The same problem naming the parameter or header at fault.
    pub fn naming(mut self, parameter: &str) -> Self {
        self.fields.get_or_insert_with(Default::default).parameter = Some(echo(parameter));
        self
    }

    /// The same problem listing the body's fields at fault (403 for a field
    /// the caller may not set, say).
    pub fn with_errors(mut self, invalid: Invalid) -> Self {
        let fields = self.fields.get_or_insert_with(Default::default);
        fields.errors = invalid.errors;
        fields.errors_omitted = invalid.omitted;
        self
    }

    /// 400: the request is not well-formed (syntax, query, header).
    pub fn bad_request(detail: impl Into<String>) -> Self {
        Self::new(Kind::Malformed, detail)
    }

    /// 400 naming a query parameter or header (its name cut short if long).
    pub fn bad_parameter(name: &str, detail: impl std::fmt::Display) -> Self {
        Self::bad_request(format!("parameter `{}` {detail}", echo(name))).naming(name)
    }

    /// 422: well-formed, but the listed fields are wrong.
    pub fn validation(invalid: Invalid) -> Self {
        let detail = invalid.to_string();
        Problem {
            fields: Some(Box::new(Fields {
                errors: invalid.errors,
                errors_omitted: invalid.omitted,
                parameter: None,
            })),
            ..Self::new(Kind::Validation, detail)
        }
    }

    /// 401: no valid credentials.
    pub fn unauthorized(detail: impl Into<String>) -> Self {
        Self::new(Kind::Unauthorized, detail)
    }

    /// 403: valid credentials without the right.
    pub fn forbidden(detail: impl Into<String>) -> Self {
        Self::new(Kind::Forbidden, detail)
    }

    /// 404.
    pub fn not_found(detail: impl Into<String>) -> Self {
        Self::new(Kind::NotFound, detail)
    }

    /// 413.
    pub fn too_large(limit: usize) -> Self {
        Self::new(
            Kind::TooLarge,
            format!("the body exceeds the limit of {limit} bytes"),
        )
    }

    /// 415.
    pub fn unsupported_media(detail: impl Into<String>) -> Self {
        Self::new(Kind::UnsupportedMediaType, detail)
    }

    /// 408: the client was too slow sending its request.
    pub fn request_timeout(detail: impl Into<String>) -> Self {
        Self::new(Kind::Timeout, detail)
    }

    /// 501: a request feature accelcal does not implement.
    pub fn not_implemented(detail: impl Into<String>) -> Self {
        Self::new(Kind::NotImplemented, detail)
    }

    /// 503 with `Retry-After`.
    pub fn unavailable(detail: impl Into<String>, retry_after: u32) -> Self {
        Self::new(Kind::Unavailable, detail).retry_after(retry_after)
    }

    /// 429 with `Retry-After`: too many failed attempts from this client.
    pub fn too_many(detail: impl Into<String>, retry_after: u64) -> Self {
        Self::new(Kind::TooManyRequests, detail)
            .retry_after(u32::try_from(retry_after).unwrap_or(u32::MAX))
    }

    /// 500: a fault of accelcal's own; the detail stays in the log.
    pub fn internal() -> Self {
        Self::new(
            Kind::Internal,
            "an internal error occurred; it has been logged with this request's id",
        )
    }

    /// The problem as a JSON document, with an optional request id.
    pub fn to_json(&self, request_id: Option<&str>) -> Vec<u8> {
        let fields = self.fields.as_deref();
        serde_json::to_vec(&ProblemBody {
            kind: format!("urn:accelcal:problem:{}", self.kind.name()),
            title: self.kind.title(),
            status: self.status.as_u16(),
            detail: &self.detail,
            errors: fields.map_or(&[], |f| f.errors.as_slice()),
            errors_omitted: fields.map_or(0, |f| f.errors_omitted),
            parameter: fields.and_then(|f| f.parameter.as_deref()),
            request_id,
        })
        .unwrap_or_default()
    }

    /// The response for this problem, with the request id in its body.
    pub fn response(&self, request_id: Option<&str>) -> Response {
        let mut res = (self.status, self.to_json(request_id)).into_response();
        let h = res.headers_mut();
        h.insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        if let Some(s) = self.retry_after {
            h.insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        if self.status == StatusCode::UNAUTHORIZED {
            h.insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"accelcal\""),
            );
        }
        res
    }
}

impl IntoResponse for Problem {
    fn into_response(self) -> Response {
        let mut res = self.response(None);
        res.extensions_mut().insert(self);
        res
    }
}

impl From<StoreError> for Problem {
    fn from(e: StoreError) -> Self {
        match e {
            StoreError::Unavailable(_) => {
                tracing::warn!(error = %e.chain(), "storage unavailable");
                Problem::unavailable("the database is unavailable; retry shortly", 2)
            }
            StoreError::Overloaded(_) => {
                tracing::warn!(error = %e, "write queue full");
                Problem::unavailable(
                    "too many submissions are waiting to be stored; retry in a second",
                    1,
                )
            }
            StoreError::Conflict(why) => Problem::new(Kind::StateConflict, why),
            _ => {
                tracing::error!(error = %e.chain(), "storage fault");
                Problem::internal()
            }
        }
    }
}

impl From<crate::app::Error> for Problem {
    fn from(e: crate::app::Error) -> Self {
        use crate::app::Error;
        match e {
            Error::Unreadable(why) => Problem::bad_request(why),
            Error::Invalid(invalid) => Problem::validation(invalid),
            Error::Forbidden { why, fields: None } => Problem::forbidden(why),
            Error::Forbidden {
                why,
                fields: Some(invalid),
            } => Problem::forbidden(why).with_errors(invalid),
            Error::NotFound(why) => Problem::not_found(why),
            Error::State(why) => Problem::new(Kind::StateConflict, why),
            Error::WrongKind(why) => Problem::new(Kind::WrongKind, why.clone())
                .with_errors(Invalid::one(Loc::Root.key("sensor_id"), why)),
            Error::InFlight => Problem::new(
                Kind::InFlight,
                "a request with this Idempotency-Key is still being processed; retry shortly",
            )
            .retry_after(1),
            Error::KeyReused => Problem::new(
                Kind::IdempotencyKeyReused,
                "this Idempotency-Key was already used with a different request body",
            )
            .naming("Idempotency-Key"),
            Error::Store(e) => Problem::from(e),
            Error::Internal => Problem::internal(),
        }
    }
}

impl From<Invalid> for Problem {
    fn from(invalid: Invalid) -> Self {
        Problem::from(crate::app::Error::from(invalid))
    }
}

impl From<BodyError> for Problem {
    fn from(e: BodyError) -> Self {
        Problem::from(crate::app::Error::from(e))
    }
}

impl From<Refused> for Problem {
    fn from(e: Refused) -> Self {
        Problem::from(crate::app::Error::from(e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_is_documented_for_integrators() {
        let readme = include_str!("../../docs/integrators.md");
        for kind in Kind::ALL {
            let row = format!("| `{}` | {} |", kind.name(), kind.status().as_u16());
            assert!(
                readme.contains(&row),
                "docs/integrators.md's problem table lacks {row}"
            );
        }
    }

    #[test]
    fn problems_are_small_and_carry_their_fields() {
        assert!(std::mem::size_of::<Problem>() <= 64);
        let p = Problem::bad_parameter(&"q".repeat(500), "is not known here");
        let doc: serde_json::Value = serde_json::from_slice(&p.to_json(Some("id-1"))).unwrap();
        assert_eq!(doc["type"], "urn:accelcal:problem:malformed");
        assert!(doc["parameter"].as_str().unwrap().chars().count() <= 65);
        assert_eq!(doc["request_id"], "id-1");
        assert!(doc.get("errors").is_none());
    }

    #[test]
    fn a_full_write_queue_is_a_retryable_503() {
        let res = Problem::from(StoreError::Overloaded(512)).response(None);
        assert_eq!(res.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(res.headers()[header::RETRY_AFTER], "1");
        assert_eq!(
            res.headers()[header::CONTENT_TYPE],
            "application/problem+json"
        );
    }

    #[test]
    fn a_record_made_from_what_changed_is_a_409_whichever_layer_maps_it() {
        let why = "temperature model m was not stored: calibration c is rejected";
        for p in [
            Problem::from(StoreError::Conflict(why.into())),
            Problem::from(crate::app::Error::from(StoreError::Conflict(why.into()))),
        ] {
            let doc: serde_json::Value = serde_json::from_slice(&p.to_json(None)).unwrap();
            assert_eq!(p.response(None).status(), StatusCode::CONFLICT);
            assert_eq!(doc["type"], "urn:accelcal:problem:state-conflict");
            assert_eq!(doc["detail"], why);
        }
    }
}
