//! Cross-cutting request handling: request ids, the access log, problem
//! bodies for every error, security headers, load shedding and timeouts.

use std::sync::Arc;
use std::time::Instant;

use axum::body::Body;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderMap, HeaderName, HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use http_body_util::BodyExt;
use tokio::sync::Semaphore;
use tracing::Instrument;
use uuid::Uuid;

use super::AppState;
use super::problem::{PROBLEM_JSON, Problem};

/// The request id header, accepted from clients and always returned.
pub static X_REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// A request id as given by the client, if it is short and plain enough to
/// log safely; otherwise a fresh UUIDv7.
fn request_id(headers: &HeaderMap) -> String {
    headers
        .get(&X_REQUEST_ID)
        .and_then(|v| v.to_str().ok())
        .filter(|s| {
            (1..=128).contains(&s.len())
                && s.chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ':'))
        })
        .map_or_else(|| Uuid::now_v7().to_string(), str::to_owned)
}

/// The outermost layer: assigns the request id, logs one line per request,
/// renders every error as a problem document carrying the request id, and
/// adds security headers.
pub async fn outer(mut req: Request, next: Next) -> Response {
    let id = request_id(req.headers());
    let value = HeaderValue::from_str(&id).expect("checked characters");
    req.headers_mut()
        .insert(X_REQUEST_ID.clone(), value.clone());
    let method = req.method().clone();
    let path = req.uri().path().to_owned();
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map(|m| m.as_str().to_owned());
    let span = tracing::info_span!("request", request_id = %id, %method, route = route.as_deref().unwrap_or("-"));
    let start = Instant::now();
    let res = next.run(req).instrument(span.clone()).await;
    let mut res = finalize_problems(res, &id).await;
    let status = res.status();
    span.in_scope(|| {
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if status.is_server_error() {
            tracing::warn!(%path, status = status.as_u16(), latency_ms = ms, "request");
        } else {
            tracing::info!(%path, status = status.as_u16(), latency_ms = ms, "request");
        }
    });
    let h = res.headers_mut();
    h.insert(X_REQUEST_ID.clone(), value);
    security_headers(h, path.starts_with("/v1/"));
    res
}

fn security_headers(h: &mut HeaderMap, api: bool) {
    let set = |h: &mut HeaderMap, name: HeaderName, v: &'static str| {
        h.entry(name).or_insert(HeaderValue::from_static(v));
    };
    set(h, header::X_CONTENT_TYPE_OPTIONS, "nosniff");
    set(h, header::X_FRAME_OPTIONS, "DENY");
    set(h, header::REFERRER_POLICY, "no-referrer");
    set(
        h,
        header::CONTENT_SECURITY_POLICY,
        "default-src 'none'; frame-ancestors 'none'",
    );
    set(
        h,
        HeaderName::from_static("cross-origin-resource-policy"),
        "same-origin",
    );
    if api {
        set(h, header::CACHE_CONTROL, "no-store");
    }
}

/// Gives every error response a problem body with the request id: handler
/// problems are re-rendered, and errors produced by the framework (unknown
/// route, wrong method, path rejections) are converted.
pub async fn finalize_problems(mut res: Response, request_id: &str) -> Response {
    let status = res.status();
    if let Some(problem) = res.extensions_mut().remove::<Problem>() {
        return rebuild(res, &problem, request_id);
    }
    if !(status.is_client_error() || status.is_server_error()) {
        return res;
    }
    let is_problem = res
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(PROBLEM_JSON.as_bytes()));
    if is_problem {
        return res;
    }
    let (parts, body) = res.into_parts();
    // Framework error bodies are short plain text; keep at most 1 KiB of it.
    let text = http_body_util::Limited::new(body, 1024)
        .collect()
        .await
        .map(|c| String::from_utf8_lossy(&c.to_bytes()).into_owned())
        .unwrap_or_default();
    let problem = match status {
        StatusCode::NOT_FOUND => Problem::not_found("no such resource"),
        StatusCode::METHOD_NOT_ALLOWED => Problem::new(
            status,
            "method-not-allowed",
            "Method not allowed",
            "this resource does not support the method; see the Allow header",
        ),
        s if s.is_server_error() => {
            tracing::error!(status = s.as_u16(), body = %text, "framework error");
            Problem::internal()
        }
        s => Problem::new(
            s,
            "malformed",
            "Malformed request",
            if text.is_empty() {
                s.canonical_reason().unwrap_or("bad request").to_owned()
            } else {
                text
            },
        ),
    };
    rebuild(
        Response::from_parts(parts, Body::empty()),
        &problem,
        request_id,
    )
}

fn rebuild(res: Response, problem: &Problem, request_id: &str) -> Response {
    let (mut parts, _) = res.into_parts();
    let fresh = problem.response(Some(request_id));
    parts.status = fresh.status();
    parts.headers.remove(header::CONTENT_LENGTH);
    for (name, value) in fresh.headers() {
        parts.headers.insert(name.clone(), value.clone());
    }
    Response::from_parts(parts, fresh.into_body())
}

/// Sheds load: at most `max_concurrent` requests are handled at once; the
/// rest are answered 503 with `Retry-After` at once instead of queueing.
/// Health probes are exempt.
pub async fn shed_load(State(limit): State<Arc<Semaphore>>, req: Request, next: Next) -> Response {
    if matches!(req.uri().path(), "/healthz" | "/readyz") {
        return next.run(req).await;
    }
    match limit.try_acquire_owned() {
        Ok(_permit) => next.run(req).await,
        Err(_) => Problem::unavailable("the server is at its concurrency limit; retry shortly", 1)
            .into_response(),
    }
}

/// Bounds the time spent handling one request (reading the body included).
pub async fn deadline(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let limit = state.limits.request_timeout;
    match tokio::time::timeout(limit, next.run(req)).await {
        Ok(res) => res,
        Err(_) => Problem::unavailable(
            format!(
                "the request was not completed within {} s; retry",
                limit.as_secs()
            ),
            2,
        )
        .into_response(),
    }
}
