//! The HTTP API: state, router and the middleware stack.
//!
//! Routes are grouped by resource in the submodules; the layers are in
//! [`stack`]; every error is a [`problem::Problem`]. A new endpoint is a
//! handler in the resource's module, one `.route` line in [`router`] and one
//! line in [`openapi`]'s list of paths.

pub mod audit;
pub mod auth;
pub mod backup;
pub mod body;
pub mod calibrations;
pub mod coefficients;
pub mod compute;
pub mod conditional;
pub mod connection;
pub mod customers;
pub mod dcc;
pub mod events;
pub mod firmware;
pub mod health;
pub mod lookup;
pub mod metrics;
pub mod openapi;
pub mod page;
pub mod problem;
pub mod query;
pub mod rendered;
pub mod reviews;
pub mod sensor_types;
pub mod sensors;
pub mod sse;
pub mod stability;
pub mod stack;
pub mod standards;
pub mod stored;
pub mod throttle;
pub mod tokens;
pub mod triad;
pub mod triads;
pub mod ui;
pub mod webhooks;

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::error_handling::HandleErrorLayer;
use axum::http::StatusCode;
use axum::routing::get;
use tokio::sync::Semaphore;
use tower::ServiceBuilder;
use tower::limit::GlobalConcurrencyLimitLayer;
use tower::load_shed::LoadShedLayer;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::map_request_body::MapRequestBodyLayer;
use tower_http::request_id::{PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::TraceLayer;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use self::problem::Problem;
use self::stack::Admission;
use crate::app::Lab;
use crate::domain::limits::{DEFAULT_BODY_BUDGET_BYTES, DEFAULT_MAX_BODY_BYTES};
use crate::store::Store;

/// Bounds on what one request may take.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Largest request body, in bytes (after decompression).
    pub max_body_bytes: usize,
    /// Bytes of request bodies being received or worked on at once; beyond
    /// it new bodies are answered 503.
    pub body_budget_bytes: usize,
    /// Time allowed to receive a body.
    pub body_timeout: Duration,
    /// Time allowed for a whole request.
    pub request_timeout: Duration,
    /// Requests worked on at once (bodies received); more are answered 503.
    pub max_concurrent: usize,
    /// Submissions parsed and calibrated at once on the blocking pool
    /// (default: the number of CPUs); more wait their turn.
    pub compute_threads: usize,
    /// Failed authentications a client address may make in a burst
    /// ([`throttle`]).
    pub auth_failure_burst: u32,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_body_bytes: DEFAULT_MAX_BODY_BYTES,
            body_budget_bytes: DEFAULT_BODY_BUDGET_BYTES,
            body_timeout: Duration::from_secs(30),
            request_timeout: Duration::from_secs(60),
            max_concurrent: 256,
            compute_threads: std::thread::available_parallelism().map_or(2, |n| n.get()),
            auth_failure_burst: throttle::BURST,
        }
    }
}

/// What every handler can reach: one shared allocation, so that the clone
/// each layer and handler takes is one reference count, not five.
#[derive(Clone)]
pub struct AppState(Arc<Shared>);

/// What [`AppState`] shares.
pub struct Shared {
    /// The database.
    pub store: Arc<dyn Store>,
    /// `SHA-256` of the configured admin token, if one is configured.
    pub admin_token_hash: Option<[u8; 32]>,
    /// Request bounds.
    pub limits: Limits,
    /// The admission budgets (bodies in flight, work slots).
    pub admission: Admission,
    /// Permits for CPU-heavy work on the blocking pool.
    pub compute: Arc<Semaphore>,
    /// The laboratory the acts work in (the same store and pool).
    pub lab: Lab,
    /// How the web pages and certificates present themselves.
    pub web: Web,
    /// Coefficients answers rendered once per calibration.
    pub rendered: coefficients::Rendered,
    /// Calibration summaries (history pages' items) rendered once each, by
    /// id and state.
    pub summaries: rendered::ById<(uuid::Uuid, crate::domain::review::State)>,
    /// Failed authentications per client address.
    pub throttle: throttle::Throttle,
    /// The live events of `GET /v1/events`.
    pub events: Arc<crate::app::events::Feed>,
    /// Wakes this replica's webhook dispatcher (an endpoint registered or
    /// redelivered: its events are due at once).
    pub deliveries: Arc<tokio::sync::Notify>,
}

impl std::ops::Deref for AppState {
    type Target = Shared;
    fn deref(&self) -> &Shared {
        &self.0
    }
}

/// Settings of the web pages and certificates.
#[derive(Clone, Debug)]
pub struct Web {
    /// The service's public base URL (`https://cal.example.com`), used for
    /// certificates' own URLs and to mark cookies `Secure`; without one,
    /// URLs are built from the request's `Host`.
    pub public_url: Option<String>,
    /// How long a web session lasts after sign-in.
    pub session_ttl: Duration,
    /// Who issues the certificates.
    pub laboratory: Laboratory,
    /// Which calibrations coefficients, compensation, as-found and
    /// stability use: approved ones only with `--require-approval`.
    pub basis: crate::domain::review::Basis,
    /// The laboratory's DCC signing key and certificate
    /// (`--dcc-signing-key`, `--dcc-signing-cert`): every DCC issued while
    /// one is configured is signed; none, and DCCs are issued unsigned.
    pub dcc_signer: Option<Arc<crate::domain::dcc_signature::Signer>>,
    /// How often `GET /v1/events` sends a heartbeat comment while nothing
    /// happens (`--events-heartbeat`).
    pub events_heartbeat: Duration,
    /// How often a replica looks for new events in the audit trail while
    /// someone listens (`--events-poll-ms`).
    pub events_poll: Duration,
    /// How webhooks are delivered (`--webhook-*`).
    pub webhooks: crate::app::delivery::Settings,
    /// How often a replica looks for statuses changed by the clock
    /// (`--status-scan`).
    pub status_scan: Duration,
}

impl Default for Web {
    fn default() -> Self {
        Web {
            public_url: None,
            session_ttl: Duration::from_secs(8 * 3600),
            laboratory: Laboratory::default(),
            basis: crate::domain::review::Basis::default(),
            dcc_signer: None,
            events_heartbeat: Duration::from_secs(15),
            events_poll: crate::app::events::POLL,
            webhooks: crate::app::delivery::Settings::default(),
            status_scan: crate::app::clock::SCAN,
        }
    }
}

/// The calibration laboratory, as its certificates name it
/// (`--lab-name`, `--lab-address`, `--lab-country`, `--lab-accreditation`,
/// `--lab-logo`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Laboratory {
    /// Its name.
    pub name: Option<String>,
    /// Its address, which is also the place of calibration.
    pub address: Option<String>,
    /// Its country, ISO 3166-1 alpha-2 (`DE`): the Digital Calibration
    /// Certificate's `countryCodeISO3166_1`.
    pub country: Option<String>,
    /// Its accreditation: body and number (`DAkkS D-K-12345-01-00`).
    pub accreditation: Option<String>,
    /// Its logo as a `data:` URI (PNG, JPEG or SVG, read at start).
    pub logo: Option<String>,
}

/// Largest logo file accepted.
pub const MAX_LOGO_BYTES: u64 = 256 * 1024;

impl Laboratory {
    /// Checks a country code: two ASCII capital letters (ISO 3166-1
    /// alpha-2), as the Digital Calibration Certificate requires.
    pub fn country_from(code: &str) -> Result<String, String> {
        if code.len() == 2 && code.bytes().all(|b| b.is_ascii_uppercase()) {
            Ok(code.to_owned())
        } else {
            Err(format!(
                "`{code}`: a country is its ISO 3166-1 alpha-2 code, two capital letters (DE, FR, US)"
            ))
        }
    }

    /// The logo at `path` as a `data:` URI, by its extension; an error
    /// names what is wrong with it.
    pub fn logo_from(path: &std::path::Path) -> Result<String, String> {
        use base64::Engine as _;
        let media = match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("png") => "image/png",
            Some("jpg" | "jpeg") => "image/jpeg",
            Some("svg") => "image/svg+xml",
            _ => {
                return Err(format!(
                    "{}: a logo must be .png, .jpg or .svg",
                    path.display()
                ));
            }
        };
        let size = std::fs::metadata(path)
            .map_err(|e| format!("{}: {e}", path.display()))?
            .len();
        if size > MAX_LOGO_BYTES {
            return Err(format!(
                "{}: {size} bytes; a logo may have at most {MAX_LOGO_BYTES}",
                path.display()
            ));
        }
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(format!(
            "data:{media};base64,{}",
            base64::engine::general_purpose::STANDARD.encode(bytes)
        ))
    }
}

impl AppState {
    /// State over `store` with `limits` and the default [`Web`] settings.
    pub fn new(store: Arc<dyn Store>, admin_token_hash: Option<[u8; 32]>, limits: Limits) -> Self {
        Self::with_web(store, admin_token_hash, limits, Web::default())
    }

    /// State over `store` with `limits` and `web`.
    pub fn with_web(
        store: Arc<dyn Store>,
        admin_token_hash: Option<[u8; 32]>,
        limits: Limits,
        web: Web,
    ) -> Self {
        let compute = Arc::new(Semaphore::new(limits.compute_threads.max(1)));
        let events = Arc::new(crate::app::events::Feed::new(
            store.clone(),
            web.events_poll,
            web.basis,
        ));
        AppState(Arc::new(Shared {
            store: store.clone(),
            admin_token_hash,
            admission: Admission::new(
                limits.body_budget_bytes,
                limits.max_body_bytes,
                limits.max_concurrent,
            ),
            compute: compute.clone(),
            lab: Lab {
                store: store.clone(),
                compute,
                basis: web.basis,
                deadline: limits.request_timeout,
            },
            web,
            limits,
            rendered: coefficients::Rendered::default(),
            summaries: rendered::ById::new(sensors::SUMMARIES),
            throttle: throttle::Throttle::new(limits.auth_failure_burst),
            events,
            deliveries: Arc::new(tokio::sync::Notify::new()),
        }))
    }

    /// Runs the work of a body of `bytes` bytes ([`Lab::compute_for`]).
    pub async fn compute_for<T: Send + 'static>(
        &self,
        bytes: usize,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, Problem> {
        Ok(self.lab.compute_for(bytes, work).await?)
    }

    /// Runs CPU-heavy work on the blocking pool ([`Lab::compute`]).
    pub async fn compute<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, Problem> {
        Ok(self.lab.compute(work).await?)
    }
}

/// The API's routes (behind admission), each handler named once: its
/// `#[utoipa::path]` gives both the route's method and path and its entry
/// in the OpenAPI document ([`openapi::document`]). Their `/v1` is written
/// out and the routes merged rather than nested: a nested router strips
/// its prefix from every request's URI (a new `Uri` each time).
pub fn api_routes() -> OpenApiRouter<AppState> {
    OpenApiRouter::default()
        .routes(routes!(calibrations::submit))
        .routes(routes!(calibrations::submit_thermal))
        .routes(routes!(triads::submit_thermal))
        .routes(routes!(calibrations::get))
        .routes(routes!(calibrations::certificate))
        .routes(routes!(calibrations::submission))
        .routes(routes!(dcc::verify))
        .routes(routes!(reviews::review))
        .routes(routes!(reviews::withdraw))
        .routes(routes!(reviews::amend))
        .routes(routes!(reviews::supersede))
        .routes(routes!(reviews::reprocess))
        .routes(routes!(reviews::signatures))
        .routes(routes!(sensors::list))
        .routes(routes!(sensors::get, sensors::update))
        .routes(routes!(sensors::history))
        .routes(routes!(coefficients::coefficients))
        .routes(routes!(coefficients::compensate))
        .routes(routes!(sensors::stability))
        .routes(routes!(sensor_types::list))
        .routes(routes!(sensor_types::get, sensor_types::put))
        .routes(routes!(customers::list_customers))
        .routes(routes!(customers::get_customer, customers::put_customer))
        .routes(routes!(customers::get_item, customers::put_item))
        .routes(routes!(standards::list))
        .routes(routes!(standards::get, standards::put))
        .routes(routes!(standards::nonconformity))
        .routes(routes!(standards::affected))
        .routes(routes!(compute::identify))
        .routes(routes!(compute::identify_thermal))
        .routes(routes!(compute::identify_thermal_triad))
        .routes(routes!(compute::fuse))
        .routes(routes!(triad::identify))
        .routes(routes!(triads::submit))
        .routes(routes!(triads::export))
        .routes(routes!(tokens::create, tokens::list))
        .routes(routes!(tokens::revoke))
        .routes(routes!(backup::backup))
        .routes(routes!(audit::list))
        .routes(routes!(events::stream))
        .routes(routes!(webhooks::put, webhooks::get, webhooks::delete))
        .routes(routes!(webhooks::list))
        .routes(routes!(webhooks::rotate))
        .routes(routes!(webhooks::redeliver))
        .routes(routes!(webhooks::deliveries))
}

/// The probes and the document itself (no admission, no token).
pub fn probe_routes() -> OpenApiRouter<AppState> {
    OpenApiRouter::default()
        .routes(routes!(health::healthz))
        .routes(routes!(health::readyz))
        .routes(routes!(health::openapi))
}

/// The whole application: routes, state and middleware.
pub fn router(state: AppState) -> Router {
    let limits = state.limits;
    let (v1, _) = api_routes().split_for_parts();
    let app = Router::new()
        .merge(probe_routes().split_for_parts().0)
        .route(
            "/",
            get(|| async { axum::response::Redirect::to("/ui/sensors") }),
        )
        .route(
            "/ui/",
            get(|| async { axum::response::Redirect::to("/ui/sensors") }),
        )
        .merge(admitted(v1, &state, stack::Bodies::Api))
        .nest("/ui", admitted(ui::router(), &state, stack::Bodies::Forms))
        .fallback(health::not_found);
    // One layer of the whole stack, not one `Router::layer` per middleware:
    // axum boxes each `layer` call's service separately and clones every
    // box on every request. Outermost first.
    app.layer(
        ServiceBuilder::new()
            .layer(axum::middleware::map_request(stack::sanitize_request_id))
            .layer(SetRequestIdLayer::new(
                stack::X_REQUEST_ID.clone(),
                stack::UuidV7,
            ))
            .layer(PropagateRequestIdLayer::new(stack::X_REQUEST_ID.clone()))
            .layer(
                TraceLayer::new_for_http()
                    .make_span_with(stack::request_span)
                    .on_request(())
                    .on_response(stack::log_response)
                    .on_failure(()),
            )
            .layer(axum::middleware::from_fn(metrics::observe))
            .layer(axum::middleware::from_fn_with_state(
                state.clone(),
                stack::finalize,
            ))
            .layer(stack::security_header(0))
            .layer(stack::security_header(1))
            .layer(stack::security_header(2))
            .layer(stack::security_header(3))
            .layer(stack::security_header(4))
            .layer(stack::security_header(5))
            .layer(CatchPanicLayer::custom(stack::panic_response))
            .layer(TimeoutLayer::with_status_code(
                StatusCode::SERVICE_UNAVAILABLE,
                limits.request_timeout,
            )),
    )
    .with_state(state)
}

/// `routes` behind admission: transfer codings checked, the body size
/// limited, the body received whole by `admit` (authenticated, within its
/// deadline and budget, gzip decoded), then a work slot or 503 (see
/// [`stack`]).
fn admitted(routes: Router<AppState>, state: &AppState, bodies: stack::Bodies) -> Router<AppState> {
    let limits = state.limits;
    routes.layer(
        ServiceBuilder::new()
            .layer(axum::middleware::map_request(stack::reject_codings))
            .layer(RequestBodyLimitLayer::new(limits.max_body_bytes))
            .layer(MapRequestBodyLayer::new(axum::body::Body::new))
            .layer(axum::middleware::from_fn_with_state(
                (state.clone(), bodies),
                stack::admit,
            ))
            .layer(HandleErrorLayer::new(stack::overloaded))
            .layer(LoadShedLayer::new())
            .layer(GlobalConcurrencyLimitLayer::with_semaphore(
                state.admission.work.clone(),
            )),
    )
}

/// The id in a path, or 404 when it is not one of ours.
pub(crate) fn path_id(raw: &str, what: &str) -> Result<uuid::Uuid, Problem> {
    uuid::Uuid::try_parse(raw).map_err(|_| {
        Problem::not_found(format!(
            "no {what} with id `{}`",
            crate::domain::text::echo(raw)
        ))
    })
}

#[cfg(test)]
mod laboratory_tests {
    use super::*;

    /// A logo is a PNG, JPEG or SVG file of at most 256 KiB; anything
    /// else is refused naming the file and why.
    #[test]
    fn a_logo_is_a_small_image() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("lab.PNG");
        std::fs::write(&png, [0x89, b'P', b'N', b'G']).unwrap();
        assert_eq!(
            Laboratory::logo_from(&png).unwrap(),
            "data:image/png;base64,iVBORw=="
        );
        let gif = dir.path().join("lab.gif");
        std::fs::write(&gif, b"GIF89a").unwrap();
        assert!(
            Laboratory::logo_from(&gif)
                .unwrap_err()
                .contains(".png, .jpg or .svg")
        );
        let big = dir.path().join("big.jpg");
        std::fs::write(&big, vec![0u8; MAX_LOGO_BYTES as usize + 1]).unwrap();
        assert!(
            Laboratory::logo_from(&big)
                .unwrap_err()
                .contains("at most 262144")
        );
        let missing = dir.path().join("none.svg");
        assert!(
            Laboratory::logo_from(&missing)
                .unwrap_err()
                .contains("none.svg")
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small bodies are evaluated where the request runs; larger ones on
    /// the blocking pool, within the compute limit.
    #[tokio::test(flavor = "current_thread")]
    async fn small_bodies_are_evaluated_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let store = crate::store::sqlite::SqliteStore::open(dir.path().join("s.db")).unwrap();
        let state = AppState::new(Arc::new(store), None, Limits::default());
        let here = std::thread::current().id();
        let ran_on = |size| {
            let state = state.clone();
            async move {
                state
                    .compute_for(size, || std::thread::current().id())
                    .await
                    .unwrap()
            }
        };
        assert_eq!(ran_on(crate::app::INLINE_BYTES).await, here);
        assert_ne!(ran_on(crate::app::INLINE_BYTES + 1).await, here);
    }
}
