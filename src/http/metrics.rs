//! Prometheus metrics: what the service records, and the recorder that
//! renders it for `--metrics-listen` (its own listener, off by default).
//!
//! | metric | type | labels |
//! |---|---|---|
//! | `accelcal_http_requests_total` | counter | `method`, `route` (template), `status` |
//! | `accelcal_http_request_duration_seconds` | histogram | `method`, `route`, `status` |
//! | `accelcal_http_requests_in_flight` | gauge | |
//! | `accelcal_submissions_total` | counter | `outcome` (`stored`, `replayed`, `refused`), `reason` (the problem type, or `none`) |
//! | `accelcal_verdicts_total` | counter | `verdict` (of stored calibrations of typed sensors) |
//! | `accelcal_storage_operation_duration_seconds` | histogram | `operation`, `outcome` |
//! | `accelcal_log_lines_dropped_total` | counter | |
//! | `accelcal_build_info` | gauge (1) | `version` |
//!
//! Routes are templates (`/v1/sensors/{sensor_id}`), never raw paths, and
//! requests no route matched count as `unmatched`: the label sets stay
//! bounded whatever clients send.

use std::collections::HashMap;
use std::sync::{LazyLock, OnceLock, RwLock};
use std::time::Instant;

use axum::extract::{MatchedPath, Request};
use axum::http::Method;
use axum::middleware::Next;
use axum::response::Response;
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

/// The problem type of an error answer, left by [`super::stack::finalize`]
/// for the metrics.
#[derive(Clone, Copy, Debug)]
pub struct ProblemName(pub &'static str);

/// Latency buckets, in seconds: 0.5 ms to 10 s.
const BUCKETS: &[f64] = &[
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0,
];

/// Batch-size buckets: powers of two up to the writer's largest batch (256).
const BATCH_BUCKETS: &[f64] = &[1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0, 256.0];

static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();

/// The process's Prometheus recorder, installed on first use (the `metrics`
/// facade has one global recorder per process).
pub fn recorder() -> anyhow::Result<PrometheusHandle> {
    if let Some(h) = HANDLE.get() {
        return Ok(h.clone());
    }
    let handle = PrometheusBuilder::new()
        .set_buckets_for_metric(Matcher::Suffix("_duration_seconds".into()), BUCKETS)?
        .set_buckets_for_metric(
            Matcher::Full("accelcal_storage_write_batch_size".into()),
            BATCH_BUCKETS,
        )?
        .install_recorder()?;
    let handle = HANDLE.get_or_init(|| handle).clone();
    metrics::gauge!("accelcal_build_info", "version" => env!("CARGO_PKG_VERSION")).set(1.0);
    describe();
    Ok(handle)
}

fn describe() {
    use metrics::{Unit, describe_counter, describe_gauge, describe_histogram};
    describe_counter!(
        "accelcal_http_requests_total",
        "HTTP requests answered, by route template and status."
    );
    describe_histogram!(
        "accelcal_http_request_duration_seconds",
        Unit::Seconds,
        "Time from the request's arrival to its answer's headers, by route template and status."
    );
    describe_gauge!(
        "accelcal_http_requests_in_flight",
        "HTTP requests being answered now."
    );
    describe_counter!(
        "accelcal_submissions_total",
        "Calibration submissions: stored, replayed (idempotent retry) or refused (by problem type)."
    );
    describe_counter!(
        "accelcal_verdicts_total",
        "Verdicts of stored calibrations of typed sensors."
    );
    describe_counter!(
        "accelcal_reviews_total",
        "Signatures recorded on calibrations: approve, reject, withdraw, supersede, confirm, hold."
    );
    describe_histogram!(
        "accelcal_storage_operation_duration_seconds",
        Unit::Seconds,
        "Latency of storage operations, by operation and outcome."
    );
    describe_histogram!(
        "accelcal_storage_write_batch_size",
        Unit::Count,
        "Writes committed together in one transaction (group commit, both engines)."
    );
    describe_counter!(
        "accelcal_sensor_cache_total",
        "Reads of a sensor's latest state, answered from memory (hit) or from the database (miss)."
    );
    describe_counter!(
        "accelcal_sensor_cache_writes_total",
        "Writes of a sensor through this process: its cached state brought up to date (kept) or dropped for the next read to fill (dropped)."
    );
    describe_counter!(
        "accelcal_log_lines_dropped_total",
        "Log lines dropped because the log writer's queue was full (standard error not read fast enough)."
    );
    describe_counter!(
        "accelcal_events_total",
        "Live events this replica read from the audit trail and handed to its GET /v1/events clients."
    );
    describe_gauge!(
        "accelcal_events_clients",
        "Clients of GET /v1/events and of the pages' GET /ui/events connected to this replica."
    );
    describe_counter!(
        "accelcal_events_clients_dropped_total",
        "Clients of GET /v1/events and /ui/events disconnected for falling more than 1024 events behind."
    );
    describe_counter!(
        "accelcal_events_clients_ended_total",
        "Streams of GET /v1/events and /ui/events ended because their token was revoked or their session ended."
    );
    describe_counter!(
        "accelcal_webhook_attempts_total",
        "Webhook delivery attempts by this replica, by outcome (delivered, failed: tried again later, abandoned: past the maximum age)."
    );
    describe_gauge!(
        "accelcal_webhook_backlog_entries",
        "Audit trail entries after the webhook endpoints' cursors, summed over endpoints (those not for an endpoint included): the outbox's depth."
    );
    describe_gauge!(
        "accelcal_webhook_failing_endpoints",
        "Webhook endpoints whose next event has failed at least once."
    );
    describe_gauge!(
        "accelcal_webhook_undelivered_age_seconds",
        "Per endpoint, the age of the event this replica last failed to deliver to it (0 once delivered): the oldest undelivered event's age."
    );
    describe_gauge!("accelcal_build_info", "Always 1; the version is a label.");
}

/// Brings the values kept outside the recorder up to date; called before
/// each scrape renders.
pub fn before_scrape() {
    metrics::counter!("accelcal_log_lines_dropped_total")
        .absolute(crate::telemetry::dropped_lines());
}

/// One request counted as in flight for as long as it lives.
struct InFlight(metrics::Gauge);

impl InFlight {
    fn new() -> Self {
        static GAUGE: OnceLock<metrics::Gauge> = OnceLock::new();
        let gauge = GAUGE
            .get_or_init(|| metrics::gauge!("accelcal_http_requests_in_flight"))
            .clone();
        gauge.increment(1.0);
        InFlight(gauge)
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        self.0.decrement(1.0);
    }
}

/// The two request metrics of one method, route and status.
#[derive(Clone)]
struct RequestMetrics {
    count: metrics::Counter,
    duration: metrics::Histogram,
}

/// [`RequestMetrics`] by route template, then method and status:
/// registered with their labels once, then updated through their handles
/// (building the labels and looking the metric up in the recorder on every
/// request cost as much as the rest of this layer). Bounded as the labels
/// are: route templates and `unmatched`, eight method labels, three-digit
/// statuses.
type ByRoute = HashMap<String, Vec<(&'static str, u16, RequestMetrics)>>;

static REQUEST_METRICS: LazyLock<RwLock<ByRoute>> = LazyLock::new(Default::default);

fn request_metrics(method: &'static str, route: &str, status: u16) -> RequestMetrics {
    let found = |map: &ByRoute| {
        map.get(route)?
            .iter()
            .find(|(m, s, _)| *m == method && *s == status)
            .map(|(_, _, metrics)| metrics.clone())
    };
    // The lock guards a cache of handles: a panic cannot leave it wrong.
    if let Some(m) = found(&REQUEST_METRICS.read().unwrap_or_else(|e| e.into_inner())) {
        return m;
    }
    let mut map = REQUEST_METRICS.write().unwrap_or_else(|e| e.into_inner());
    if let Some(m) = found(&map) {
        return m;
    }
    let labels = [
        ("method", method.to_owned()),
        ("route", route.to_owned()),
        ("status", status.to_string()),
    ];
    let metrics = RequestMetrics {
        count: metrics::counter!("accelcal_http_requests_total", &labels),
        duration: metrics::histogram!("accelcal_http_request_duration_seconds", &labels),
    };
    map.entry(route.to_owned())
        .or_default()
        .push((method, status, metrics.clone()));
    metrics
}

/// Records every request: count and latency by method, route template and
/// status; submissions by outcome. Nothing is recorded, at no cost, when
/// the service runs without `--metrics-listen`.
pub async fn observe(req: Request, next: Next) -> Response {
    if HANDLE.get().is_none() {
        return next.run(req).await;
    }
    let _in_flight = InFlight::new();
    let started = Instant::now();
    let method = method_label(req.method());
    let route = req.extensions().get::<MatchedPath>().cloned();
    let res = next.run(req).await;
    let status = res.status();
    let route = route.as_ref().map_or("unmatched", MatchedPath::as_str);
    let metrics = request_metrics(method, route, status.as_u16());
    metrics.count.increment(1);
    metrics.duration.record(started.elapsed().as_secs_f64());
    if method == "POST" && route == "/v1/calibrations" {
        let (outcome, reason) = if status.is_success() {
            let replayed = res.headers().contains_key("idempotent-replayed");
            (if replayed { "replayed" } else { "stored" }, "none")
        } else {
            let reason = res
                .extensions()
                .get::<ProblemName>()
                .map_or("unknown", |p| p.0);
            ("refused", reason)
        };
        metrics::counter!("accelcal_submissions_total", "outcome" => outcome, "reason" => reason)
            .increment(1);
    }
    res
}

/// The method as a label: the standard ones by name, anything else `other`.
fn method_label(m: &Method) -> &'static str {
    match *m {
        Method::GET => "GET",
        Method::POST => "POST",
        Method::PUT => "PUT",
        Method::DELETE => "DELETE",
        Method::HEAD => "HEAD",
        Method::OPTIONS => "OPTIONS",
        Method::PATCH => "PATCH",
        _ => "other",
    }
}
