//! RFC 9457 problem details: the one error shape of every 4xx and 5xx.
//!
//! ```json
//! {"type": "urn:accelcal:problem:validation", "title": "Invalid submission",
//!  "status": 422, "detail": "2 problems in the request body",
//!  "errors": [{"pointer": "/runs/2/readings/1", "detail": "must not be empty"}],
//!  "request_id": "…"}
//! ```
//!
//! Handlers return [`Problem`]; the response carries a copy in its extensions
//! so that the outermost middleware can add the `request_id`
//! (see [`super::middleware::finalize_problems`]).

use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;

use crate::input::FieldError;
use crate::store::StoreError;

/// The media type of problem documents.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// A problem document with its HTTP status and headers.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// HTTP status.
    pub status: StatusCode,
    /// Short name of the problem type (`validation`, `unauthorized`, …).
    pub kind: &'static str,
    /// Human title of the problem type.
    pub title: &'static str,
    /// What happened in this occurrence.
    pub detail: String,
    /// Field-level problems, for validation failures.
    pub errors: Vec<FieldError>,
    /// The query or path parameter at fault, for malformed parameters.
    pub parameter: Option<String>,
    /// `Retry-After` seconds, for retryable problems.
    pub retry_after: Option<u32>,
}

#[derive(Serialize)]
struct Body<'a> {
    #[serde(rename = "type")]
    kind: String,
    title: &'a str,
    status: u16,
    detail: &'a str,
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    errors: &'a [FieldError],
    #[serde(skip_serializing_if = "Option::is_none")]
    parameter: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    request_id: Option<&'a str>,
}

impl Problem {
    /// A problem of the given status, kind and title.
    pub fn new(
        status: StatusCode,
        kind: &'static str,
        title: &'static str,
        detail: impl Into<String>,
    ) -> Self {
        Problem {
            status,
            kind,
            title,
            detail: detail.into(),
            errors: Vec::new(),
            parameter: None,
            retry_after: None,
        }
    }

    /// 400: the request is not well-formed (syntax, query, path).
    pub fn bad_request(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::BAD_REQUEST,
            "malformed",
            "Malformed request",
            detail,
        )
    }

    /// 400 naming a query or path parameter.
    pub fn bad_parameter(name: &str, detail: impl std::fmt::Display) -> Self {
        Problem {
            parameter: Some(name.to_owned()),
            ..Self::bad_request(format!("parameter `{name}` {detail}"))
        }
    }

    /// 422: well-formed, but the listed fields are wrong.
    pub fn validation(errors: Vec<FieldError>) -> Self {
        let detail = match errors.as_slice() {
            [one] if one.pointer.is_empty() => one.detail.clone(),
            [one] => format!("{}: {}", one.pointer, one.detail),
            many => format!("{} problems in the request body", many.len()),
        };
        Problem {
            errors,
            ..Self::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                "validation",
                "Invalid request content",
                detail,
            )
        }
    }

    /// 401: no valid credentials.
    pub fn unauthorized(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "Authentication required",
            detail,
        )
    }

    /// 403: valid credentials without the right.
    pub fn forbidden(detail: impl Into<String>) -> Self {
        Self::new(StatusCode::FORBIDDEN, "forbidden", "Not allowed", detail)
    }

    /// 404.
    pub fn not_found(detail: impl Into<String>) -> Self {
        Self::new(StatusCode::NOT_FOUND, "not-found", "Not found", detail)
    }

    /// 413.
    pub fn too_large(limit: usize) -> Self {
        Self::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            "too-large",
            "Request body too large",
            format!("the body exceeds the limit of {limit} bytes"),
        )
    }

    /// 415.
    pub fn unsupported_media(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "unsupported-media-type",
            "Unsupported media type",
            detail,
        )
    }

    /// 408: the client was too slow sending its request.
    pub fn request_timeout(detail: impl Into<String>) -> Self {
        Self::new(
            StatusCode::REQUEST_TIMEOUT,
            "timeout",
            "Request timeout",
            detail,
        )
    }

    /// 503 with `Retry-After`.
    pub fn unavailable(detail: impl Into<String>, retry_after: u32) -> Self {
        Problem {
            retry_after: Some(retry_after),
            ..Self::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "unavailable",
                "Service unavailable",
                detail,
            )
        }
    }

    /// 500: a fault of accelcal's own; the detail stays in the log.
    pub fn internal() -> Self {
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            "internal",
            "Internal error",
            "an internal error occurred; it has been logged with this request's id",
        )
    }

    /// The problem as a JSON document, with an optional request id.
    pub fn to_json(&self, request_id: Option<&str>) -> Vec<u8> {
        serde_json::to_vec(&Body {
            kind: format!("urn:accelcal:problem:{}", self.kind),
            title: self.title,
            status: self.status.as_u16(),
            detail: &self.detail,
            errors: &self.errors,
            parameter: self.parameter.as_deref(),
            request_id,
        })
        .expect("problem serialises")
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
            StoreError::Unavailable(why) => {
                tracing::warn!(error = %why, "storage unavailable");
                Problem::unavailable("the database is unavailable; retry shortly", 2)
            }
            StoreError::Corrupt(why) => {
                tracing::error!(error = %why, "stored data failed to decode");
                Problem::internal()
            }
        }
    }
}

impl From<Vec<FieldError>> for Problem {
    fn from(errors: Vec<FieldError>) -> Self {
        Problem::validation(errors)
    }
}
