//! The middleware stack, outermost first:
//!
//! 1. request ids (tower-http `SetRequestId`/`PropagateRequestId`; a
//!    client's own id is kept when it is short, plain and not a token);
//! 2. one log line per request (tower-http `Trace`);
//! 3. [`finalize`]: every error becomes a problem document carrying the
//!    request id;
//! 4. the [`SECURITY_HEADERS`] (tower-http `SetResponseHeader`, each kept
//!    where the answer set its own);
//! 5. a panic becomes a 500 problem (tower-http `CatchPanic`);
//! 6. the whole-request deadline (tower-http `Timeout`, 503);
//!
//! and, for `/v1` only (health probes are exempt):
//!
//! 7. [`reject_codings`]: transfer codings other than chunked are 501;
//! 8. the size limit on the bytes as sent (tower-http `RequestBodyLimit`,
//!    413 from `Content-Length` before reading);
//! 9. [`admit`]: the sender authenticated, then the body received whole —
//!    within its own deadline, its sender's share of a budget of bytes being
//!    received at once, gzip decoded (every member) and the size limit
//!    applied after decoding — before the request competes for a slot
//!    (the pages' forms: [`admit_form`]);
//! 10. load shedding over a global concurrency limit (tower), 503 at once.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::body::Body;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use http_body_util::{BodyExt, LengthLimitError, Limited};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tower_http::request_id::{MakeRequestId, RequestId};
use tower_http::set_header::SetResponseHeaderLayer;

use super::AppState;
use super::auth::{ClientAddr, bearer};
use super::problem::{Kind, PROBLEM_JSON, Problem};
use crate::domain::auth;
use crate::domain::text::echo;

/// The request id header, accepted from clients and always returned.
pub static X_REQUEST_ID: axum::http::HeaderName =
    axum::http::HeaderName::from_static("x-request-id");

/// New request ids: UUIDv7 (time-ordered).
#[derive(Clone, Copy, Default)]
pub struct UuidV7;

impl MakeRequestId for UuidV7 {
    fn make_request_id<B>(&mut self, _: &axum::http::Request<B>) -> Option<RequestId> {
        HeaderValue::from_str(&uuid::Uuid::now_v7().to_string())
            .ok()
            .map(RequestId::new)
    }
}

/// Drops a client's `x-request-id` unless it is 1–128 characters of
/// `[A-Za-z0-9._:-]` and does not hold a token: it goes into every log line.
pub async fn sanitize_request_id(mut req: Request) -> Request {
    let usable = req
        .headers()
        .get(&X_REQUEST_ID)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|s| {
            (1..=128).contains(&s.len())
                && s.chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ':'))
                && !auth::holds_token(s)
        });
    if !usable {
        req.headers_mut().remove(&X_REQUEST_ID);
    }
    req
}

/// The span of one request: its id, method, route template and path (cut
/// short, any pasted token redacted).
pub fn request_span(req: &Request) -> tracing::Span {
    let id = req
        .headers()
        .get(&X_REQUEST_ID)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("-");
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or("-", MatchedPath::as_str);
    tracing::info_span!(
        "request",
        request_id = %id,
        method = %req.method(),
        route = %route,
        path = %echo(req.uri().path()),
    )
}

/// The request's log line: status and latency, a warning for 5xx.
pub fn log_response(res: &Response, latency: Duration, _: &tracing::Span) {
    let status = res.status().as_u16();
    // Milliseconds to the microsecond: `0.833`, not `0.8329369999999999`.
    let ms = latency.as_micros() as f64 / 1e3;
    if res.status().is_server_error() {
        tracing::warn!(status, latency_ms = ms, "request");
    } else {
        tracing::info!(status, latency_ms = ms, "request");
    }
}

/// The security headers of every answer (each kept when a handler set its own).
pub const SECURITY_HEADERS: [(&str, &str); 6] = [
    ("x-content-type-options", "nosniff"),
    ("x-frame-options", "DENY"),
    ("referrer-policy", "no-referrer"),
    (
        "content-security-policy",
        "default-src 'none'; frame-ancestors 'none'",
    ),
    ("cross-origin-resource-policy", "same-origin"),
    ("cache-control", "no-store"),
];

/// The layer setting `SECURITY_HEADERS[i]` where the answer does not set
/// it itself (tower-http `SetResponseHeader`).
pub fn security_header(i: usize) -> SetResponseHeaderLayer<HeaderValue> {
    let (name, value) = SECURITY_HEADERS[i];
    SetResponseHeaderLayer::if_not_present(
        header::HeaderName::from_static(name),
        HeaderValue::from_static(value),
    )
}

/// Gives every error response a problem body with the request id: handler
/// problems are re-rendered with it, and bare errors from the framework and
/// the layers below (unknown route, wrong method, size limit, unsupported
/// encoding, the request deadline, a panic) become problems with fixed
/// texts — never a library's own message.
pub async fn finalize(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let request_id = req
        .headers()
        .get(&X_REQUEST_ID)
        .and_then(|v| v.to_str().ok())
        .map(str::to_owned);
    let encoding = req
        .headers()
        .get(header::CONTENT_ENCODING)
        .and_then(|v| v.to_str().ok())
        .map(echo);
    let mut res = next.run(req).await;
    let id = request_id.as_deref();
    if let Some(problem) = res.extensions_mut().remove::<Problem>() {
        return rebuild(res, &problem, id);
    }
    let status = res.status();
    let content_type = res.headers().get(header::CONTENT_TYPE);
    let is_problem =
        content_type.is_some_and(|v| v.as_bytes().starts_with(PROBLEM_JSON.as_bytes()));
    // The pages answer their errors as pages (`ui::UiError`).
    let is_page = content_type.is_some_and(|v| v.as_bytes().starts_with(b"text/html"));
    if !(status.is_client_error() || status.is_server_error()) || is_problem || is_page {
        return res;
    }
    let limits = &state.limits;
    let problem = match status {
        StatusCode::NOT_FOUND => Problem::not_found("no such resource; see /openapi.yaml"),
        StatusCode::METHOD_NOT_ALLOWED => Problem::new(
            Kind::MethodNotAllowed,
            "this resource does not support the method; see the Allow header",
        ),
        StatusCode::PAYLOAD_TOO_LARGE => Problem::too_large(limits.max_body_bytes),
        StatusCode::UNSUPPORTED_MEDIA_TYPE => Problem::unsupported_media(format!(
            "Content-Encoding `{}` is not accepted; send gzip or no encoding",
            encoding.unwrap_or_default()
        )),
        StatusCode::SERVICE_UNAVAILABLE => Problem::unavailable(
            format!(
                "the request was not completed within {} s; retry",
                limits.request_timeout.as_secs()
            ),
            2,
        ),
        s if s.is_server_error() => {
            tracing::error!(status = s.as_u16(), "framework error");
            Problem::internal()
        }
        s => Problem::bad_request(s.canonical_reason().unwrap_or("bad request")).with_status(s),
    };
    rebuild(res, &problem, id)
}

fn rebuild(res: Response, problem: &Problem, request_id: Option<&str>) -> Response {
    let (mut parts, _) = res.into_parts();
    let fresh = problem.response(request_id);
    parts.status = fresh.status();
    parts
        .extensions
        .insert(super::metrics::ProblemName(problem.kind.name()));
    parts.headers.remove(header::CONTENT_LENGTH);
    for (name, value) in fresh.headers() {
        parts.headers.insert(name.clone(), value.clone());
    }
    Response::from_parts(parts, fresh.into_body())
}

/// A panic in a handler: logged, answered with an opaque 500 problem.
pub fn panic_response(_: Box<dyn std::any::Any + Send + 'static>) -> Response<String> {
    tracing::error!("a handler panicked");
    let body = String::from_utf8(Problem::internal().to_json(None)).unwrap_or_default();
    let mut res = Response::new(body);
    *res.status_mut() = StatusCode::INTERNAL_SERVER_ERROR;
    res.headers_mut()
        .insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
    res
}

/// 501 for a transfer coding other than `chunked` (`gzip, chunked` and the
/// like): the body would otherwise reach the handler still encoded.
pub async fn reject_codings(req: Request) -> Result<Request, Problem> {
    for value in req.headers().get_all(header::TRANSFER_ENCODING) {
        let text = value.to_str().unwrap_or("?");
        for coding in text.split(',').map(str::trim) {
            if !coding.eq_ignore_ascii_case("chunked") {
                return Err(Problem::not_implemented(format!(
                    "Transfer-Encoding `{}` is not supported; send the body plain or chunked \
                     (Content-Encoding: gzip compresses it)",
                    echo(coding)
                )));
            }
        }
    }
    Ok(req)
}

/// The budgets of admission: bytes of bodies in flight, and requests being
/// worked on. `/readyz` fails while either is exhausted.
#[derive(Clone, Debug)]
pub struct Admission {
    /// KiB of request bodies being received or worked on.
    pub bodies: Arc<Semaphore>,
    /// The body budget in KiB (the semaphore's size).
    pub body_budget_kib: usize,
    /// The most KiB of the budget one principal may hold at once.
    pub share_kib: usize,
    /// KiB held, by principal id.
    held: Arc<Mutex<HashMap<String, usize>>>,
    /// Slots for requests being worked on (the concurrency limit).
    pub work: Arc<Semaphore>,
}

/// A principal's charge on the body budget, given back when dropped.
struct Charge {
    _permit: OwnedSemaphorePermit,
    held: Arc<Mutex<HashMap<String, usize>>>,
    who: String,
    kib: usize,
}

impl Drop for Charge {
    fn drop(&mut self) {
        let mut held = self.held.lock().expect("admission lock");
        if let Some(k) = held.get_mut(&self.who) {
            *k = k.saturating_sub(self.kib);
            if *k == 0 {
                held.remove(&self.who);
            }
        }
    }
}

impl Admission {
    /// Budgets for `body_budget_bytes` of bodies, of which one principal may
    /// hold a quarter or one largest body (`max_body_bytes`), whichever is
    /// more, and `max_concurrent` requests.
    pub fn new(body_budget_bytes: usize, max_body_bytes: usize, max_concurrent: usize) -> Self {
        let kib = body_budget_bytes.div_ceil(1024).max(1);
        let share = (kib / 4).max(max_body_bytes.div_ceil(1024)).clamp(1, kib);
        Admission {
            bodies: Arc::new(Semaphore::new(kib)),
            body_budget_kib: kib,
            share_kib: share,
            held: Arc::default(),
            work: Arc::new(Semaphore::new(max_concurrent.max(1))),
        }
    }

    /// Why the server cannot take more work right now, if it cannot.
    pub fn saturated(&self) -> Option<&'static str> {
        if self.work.available_permits() == 0 {
            Some("every request slot is taken")
        } else if self.bodies.available_permits() == 0 {
            Some("the budget of request bodies in flight is spent")
        } else {
            None
        }
    }

    /// Charges `kib` to `who`: 503 when that would pass the principal's
    /// share or the budget is spent.
    fn charge(&self, who: &str, kib: usize) -> Result<Charge, Problem> {
        let mut held = self.held.lock().expect("admission lock");
        let mine = held.get(who).copied().unwrap_or(0);
        if mine + kib > self.share_kib {
            return Err(Problem::unavailable(
                format!(
                    "this token already has {mine} KiB of request bodies in flight, and may \
                     have at most {} KiB at once; retry when one has been answered",
                    self.share_kib
                ),
                1,
            ));
        }
        let permit = self
            .bodies
            .clone()
            .try_acquire_many_owned(kib as u32)
            .map_err(|_| {
                Problem::unavailable(
                    "the server is receiving as many request bodies as it holds at once; \
                     retry shortly",
                    1,
                )
            })?;
        *held.entry(who.to_owned()).or_insert(0) += kib;
        Ok(Charge {
            _permit: permit,
            held: self.held.clone(),
            who: who.to_owned(),
            kib,
        })
    }
}

/// Which bodies a group of routes receives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bodies {
    /// The API's: authenticated by a bearer token ([`admit`]).
    Api,
    /// The pages' forms ([`admit_form`]).
    Forms,
}

/// Receives the API's request bodies: the sender is authenticated first —
/// nobody without a valid token holds any part of the shared budget — then
/// the body's size (declared, or the limit when unknown) is charged to the
/// budget of bytes in flight and to the principal's share of it (503 at
/// once when either is spent), and the body is received whole before the
/// request competes for a work slot, so a client trickling its body holds
/// only its own connection and its share, never a slot that a ready request
/// needs. The body must arrive within the body deadline (408) and, once
/// decompressed, within the size limit (413). A gzip body is decoded whole on
/// the compute pool — every member (RFC 1952 allows several), nothing after
/// the last — and its decoded size is charged too (503 past the share or the
/// budget), so the memory bodies hold is bounded by the budget plus one
/// largest body per compute thread.
///
/// The authenticated principal goes in the request's extensions, so that the
/// handler does not authenticate again.
pub async fn admit(
    State((state, bodies)): State<(AppState, Bodies)>,
    req: Request,
    next: Next,
) -> Response {
    use http_body::Body as _;
    if bodies == Bodies::Forms {
        return admit_form(&state, req, next).await;
    }
    let limits = state.limits;
    let hint = req.body().size_hint();
    if hint.exact() == Some(0) {
        return next.run(req).await;
    }
    let client = req.extensions().get::<ClientAddr>().copied();
    let principal = match bearer(&state, req.headers(), client).await {
        Ok(p) => p,
        Err(problem) => return problem.into_response(),
    };
    let gzipped = match coding(req.headers()) {
        Ok(g) => g,
        Err(problem) => return problem.into_response(),
    };
    let weight = hint
        .exact()
        .map_or(limits.max_body_bytes, |n| n as usize)
        .min(limits.max_body_bytes)
        .div_ceil(1024)
        .clamp(1, state.admission.body_budget_kib);
    let _charge = match state.admission.charge(&principal.id, weight) {
        Ok(c) => c,
        Err(problem) => return problem.into_response(),
    };
    tracing::debug!(budget_kib = weight, "receiving a request body");
    let (mut parts, body) = req.into_parts();
    let mut bytes = match receive(body, limits.max_body_bytes, limits.body_timeout).await {
        Ok(b) => b,
        Err(problem) => return problem.into_response(),
    };
    let mut _decoded = None;
    if gzipped {
        // Always on the compute pool, whatever its size as sent: a few KiB
        // of gzip may decode to the largest body, and the pool's threads
        // bound how many are being decoded at once.
        let max = limits.max_body_bytes;
        bytes = match state.compute(move || gunzip(&bytes, max)).await {
            Ok(Ok(b)) => b,
            Ok(Err(problem)) | Err(problem) => return problem.into_response(),
        };
        // The decoded body is held from here on: charged as well.
        let more = bytes.len().div_ceil(1024).saturating_sub(weight);
        if more > 0 {
            match state.admission.charge(&principal.id, more) {
                Ok(c) => _decoded = Some(c),
                Err(problem) => return problem.into_response(),
            }
        }
        parts.headers.remove(header::CONTENT_ENCODING);
        parts.headers.remove(header::CONTENT_LENGTH);
    }
    parts.extensions.insert(principal);
    next.run(Request::from_parts(parts, Body::from(bytes)))
        .await
}

/// Largest body of a page's form (sign-in, sign-out): a few hundred bytes.
pub const FORM_BYTES: usize = 16 * 1024;

/// Receives the pages' form bodies: no token comes with them (the sign-in
/// form carries one), so they take nothing of the shared budget and may be
/// at most [`FORM_BYTES`], unencoded, within the body deadline.
async fn admit_form(state: &AppState, req: Request, next: Next) -> Response {
    use http_body::Body as _;
    if req.body().size_hint().exact() == Some(0) {
        return next.run(req).await;
    }
    if req.headers().contains_key(header::CONTENT_ENCODING) {
        return Problem::unsupported_media("a form is sent without Content-Encoding")
            .into_response();
    }
    let (parts, body) = req.into_parts();
    match receive(body, FORM_BYTES, state.limits.body_timeout).await {
        Ok(bytes) => {
            next.run(Request::from_parts(parts, Body::from(bytes)))
                .await
        }
        Err(problem) => problem.into_response(),
    }
}

/// Whether the body is gzip-encoded: `gzip` (or `x-gzip`) and `identity`
/// are read, anything else (another coding, or several) is 415.
fn coding(headers: &axum::http::HeaderMap) -> Result<bool, Problem> {
    let mut gzip = false;
    for value in headers.get_all(header::CONTENT_ENCODING) {
        let text = value.to_str().unwrap_or("?");
        for c in text.split(',').map(str::trim).filter(|c| !c.is_empty()) {
            if c.eq_ignore_ascii_case("identity") {
                continue;
            }
            if (c.eq_ignore_ascii_case("gzip") || c.eq_ignore_ascii_case("x-gzip")) && !gzip {
                gzip = true;
                continue;
            }
            return Err(Problem::unsupported_media(format!(
                "Content-Encoding `{}` is not accepted; send gzip (once) or no encoding",
                echo(text)
            )));
        }
    }
    Ok(gzip)
}

/// A body received whole within `limit` bytes and `deadline`.
async fn receive(body: Body, limit: usize, deadline: Duration) -> Result<Bytes, Problem> {
    let read = Limited::new(body, limit).collect();
    match tokio::time::timeout(deadline, read).await {
        Err(_) => Err(Problem::request_timeout(format!(
            "the body was not received within {} s",
            deadline.as_secs()
        ))),
        Ok(Ok(collected)) => Ok(collected.to_bytes()),
        Ok(Err(e)) if too_large(e.as_ref()) => Err(Problem::too_large(limit)),
        Ok(Err(e)) => {
            tracing::debug!(error = %e, "a body could not be read");
            Err(Problem::bad_request(
                "the body could not be read: a malformed chunked encoding, \
                 or the connection closed early",
            ))
        }
    }
}

/// A gzip body decoded whole: every member in turn (RFC 1952 §2.2: a gzip
/// file is a series of members), at most `max` bytes (413 past it), and
/// nothing after the last member — trailing bytes that are not a member are
/// a 400, never silently dropped.
pub fn gunzip(compressed: &[u8], max: usize) -> Result<Bytes, Problem> {
    use std::io::Read as _;
    let mut out = Vec::new();
    let mut decoder = flate2::read::MultiGzDecoder::new(compressed).take(max as u64 + 1);
    if let Err(e) = decoder.read_to_end(&mut out) {
        tracing::debug!(error = %e, "a gzip body could not be decoded");
        return Err(Problem::bad_request(
            "the gzip body could not be decoded: a malformed or truncated member, or bytes \
             after the last member that are not a gzip member",
        ));
    }
    if out.len() > max {
        return Err(Problem::too_large(max));
    }
    Ok(Bytes::from(out))
}

/// Whether a body error is (or wraps) the size limit's: the limit applies
/// both to the bytes as sent and, inside, to the decompressed bytes.
fn too_large(e: &(dyn std::error::Error + 'static)) -> bool {
    let mut current = Some(e);
    while let Some(err) = current {
        if err.is::<LengthLimitError>() {
            return true;
        }
        current = err.source();
    }
    false
}

/// The answer when every work slot is taken: 503 at once, not a queue.
pub async fn overloaded(_: tower::BoxError) -> Problem {
    Problem::unavailable("the server is at its concurrency limit; retry shortly", 1)
}
