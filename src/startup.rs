//! Building and running the server: configuration, the accept loop with
//! connection-level limits, and graceful shutdown.
//!
//! ```no_run
//! # async fn run() -> anyhow::Result<()> {
//! use accelcal::startup::{Application, Config};
//! let app = Application::build(Config::for_tests("test.db", "a-long-admin-token-for-tests")).await?;
//! println!("listening on port {}", app.port());
//! app.run_until_stopped(std::future::pending()).await
//! # }
//! ```

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

pub use crate::http::openapi::document as openapi_document;
pub use crate::http::problem::Problem;
pub use crate::http::{Laboratory, Limits, Web};

use crate::domain::auth::{self, Role};
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::{TokenRequest, issue};
use crate::http::auth::ClientAddr;
use crate::http::connection::ProblemIo;
use crate::http::{self, AppState};
use crate::store::{self, Store};
use metrics_exporter_prometheus::PrometheusHandle;

/// Everything `accelcal serve` needs.
#[derive(Clone, Debug)]
pub struct Config {
    /// Address to bind (`127.0.0.1:0` picks a free port).
    pub listen: String,
    /// Database URL or path.
    pub database: String,
    /// A configured admin token, if any.
    pub admin_token: Option<String>,
    /// Request limits.
    pub limits: Limits,
    /// Time allowed to receive a request's headers.
    pub header_timeout: Duration,
    /// Open connections at most; further clients wait in the listen backlog.
    pub max_connections: usize,
    /// Time allowed for in-flight requests to finish at shutdown.
    pub shutdown_grace: Duration,
    /// Web pages and certificates.
    pub web: Web,
    /// Where to serve Prometheus metrics, if anywhere.
    pub metrics_listen: Option<String>,
    /// Free bytes a SQLite database's disk must have for `/readyz` to pass.
    pub min_free_disk_bytes: u64,
}

impl Config {
    /// A configuration for tests: a free loopback port and the given database.
    pub fn for_tests(database: &str, admin_token: &str) -> Self {
        Config {
            listen: "127.0.0.1:0".into(),
            database: database.into(),
            admin_token: Some(admin_token.into()),
            limits: Limits::default(),
            header_timeout: Duration::from_secs(10),
            max_connections: 1024,
            shutdown_grace: Duration::from_secs(30),
            web: Web::default(),
            metrics_listen: None,
            min_free_disk_bytes: store::sqlite::MIN_FREE_BYTES,
        }
    }
}

/// The hash of a configured admin token, if it is strong enough: at least
/// [`auth::MIN_ADMIN_TOKEN_BITS`] by [`auth::estimated_bits`]. A weak one
/// refuses the start, saying how to make a good one.
pub fn strong_admin_token(token: &str) -> anyhow::Result<[u8; 32]> {
    let bits = auth::estimated_bits(token);
    if bits < auth::MIN_ADMIN_TOKEN_BITS {
        anyhow::bail!(
            "the configured admin token (ACCELCAL_ADMIN_TOKEN or --admin-token) is too weak: \
             about {bits:.0} bits of entropy where {min:.0} are needed; make one with \
             `head -c 32 /dev/urandom | base64`",
            min = auth::MIN_ADMIN_TOKEN_BITS
        );
    }
    Ok(auth::hash(token))
}

/// The laboratory's DCC signer from `key` and `cert` (issue 46), checked
/// at start: the key readable by the service's user only, PEM PKCS#8, RSA
/// of at least 2048 bits or ECDSA P-256, the certificate's, the certificate
/// valid now. A refusal names the file at fault and why; the key is never
/// logged.
pub fn dcc_signer(
    key: &std::path::Path,
    cert: &std::path::Path,
) -> anyhow::Result<crate::domain::dcc_signature::Signer> {
    use std::os::unix::fs::PermissionsExt as _;
    let named = |flag: &str, path: &std::path::Path, e: &dyn std::fmt::Display| {
        anyhow::anyhow!("{flag} {}: {e}", path.display())
    };
    let mode = std::fs::metadata(key)
        .map_err(|e| named("--dcc-signing-key", key, &e))?
        .permissions()
        .mode();
    if mode & 0o077 != 0 {
        return Err(named(
            "--dcc-signing-key",
            key,
            &format!(
                "may be read by others than its owner (mode {:o}); a signing key is kept \
                 like the database: `chmod 600 {}`",
                mode & 0o777,
                key.display()
            ),
        ));
    }
    let key_pem = std::fs::read(key).map_err(|e| named("--dcc-signing-key", key, &e))?;
    let cert_pem = std::fs::read(cert).map_err(|e| named("--dcc-signing-cert", cert, &e))?;
    let signer =
        crate::domain::dcc_signature::Signer::from_pem(&key_pem, &cert_pem, Timestamp::now())
            .map_err(|e| match e.is_certificate() {
                true => named("--dcc-signing-cert", cert, &e),
                false => named("--dcc-signing-key", key, &e),
            })?;
    let c = signer.certificate();
    tracing::info!(
        subject = %c.subject,
        certificate_sha256 = %c.sha256,
        not_after = %c.not_after,
        "Digital Calibration Certificates are signed"
    );
    Ok(signer)
}

/// A bound, ready-to-run server.
pub struct Application {
    listener: TcpListener,
    metrics: Option<(TcpListener, PrometheusHandle)>,
    state: AppState,
    config: Config,
}

impl Application {
    /// Opens and migrates the database, sets up the admin token and binds.
    pub async fn build(config: Config) -> anyhow::Result<Self> {
        let admin_token_hash = match &config.admin_token {
            Some(t) => Some(strong_admin_token(t)?),
            None => None,
        };
        let store = store::open_with(&config.database, config.min_free_disk_bytes)
            .await
            .with_context(|| format!("opening database {}", config.database))?;
        store::copy::refuse_unfinished(store.as_ref()).await?;
        // The settings that change decisions, in the audit trail when they
        // differ from those the service last started with.
        let mut settings = serde_json::Map::new();
        settings.insert(
            "require_approval".into(),
            (config.web.basis == crate::domain::review::Basis::ApprovedOnly).into(),
        );
        // The laboratory's identity, which every certificate issued from
        // now on prints (issued ones keep theirs): a change at a start is
        // an entry of the trail. The logo by its SHA-256.
        let lab = &config.web.laboratory;
        settings.insert(
            "laboratory".into(),
            serde_json::json!({
                "name": lab.name,
                "address": lab.address,
                "country": lab.country,
                "accreditation": lab.accreditation,
                "logo_sha256": lab.logo.as_ref().map(|l| {
                    use sha2::Digest;
                    hex::encode(sha2::Sha256::digest(l.as_bytes()))
                }),
                "public_url": config.web.public_url,
            }),
        );
        // Who signs the DCCs (by certificate; never the key), so that the
        // trail shows when the key was rotated or signing switched off.
        if let Some(signer) = &config.web.dcc_signer {
            let c = signer.certificate();
            settings.insert(
                "dcc_signing_certificate".into(),
                serde_json::json!({"subject": c.subject, "sha256": c.sha256, "not_after": c.not_after}),
            );
        }
        if store.configure(settings).await? {
            tracing::info!(basis = ?config.web.basis, "configuration recorded in the audit trail");
        }
        if let Some(url) = &config.web.public_url
            && !(url.starts_with("http://") || url.starts_with("https://"))
        {
            anyhow::bail!("the public URL must start with http:// or https:// (got {url})");
        }
        let state = AppState::with_web(store, admin_token_hash, config.limits, config.web.clone());
        let metrics = match &config.metrics_listen {
            Some(addr) => {
                let handle =
                    http::metrics::recorder().context("installing the metrics recorder")?;
                let listener = TcpListener::bind(addr)
                    .await
                    .with_context(|| format!("binding the metrics listener {addr}"))?;
                Some((listener, handle))
            }
            None => None,
        };
        if admin_token_hash.is_none() && !state.store.has_admin_token().await? {
            let request = TokenRequest {
                role: Role::Admin,
                station_id: None,
                label: Some("first admin (created at start)".into()),
                holder: None,
            };
            let (record, created) =
                issue(request, Timestamp::now()).context("creating the first admin token")?;
            state
                .store
                .insert_token(record, crate::domain::audit::Actor::service())
                .await?;
            println!(
                "accelcal: no admin token was configured or stored; created one (shown only now):"
            );
            println!("{}", created.token);
            tracing::warn!(token_id = %created.id, "created the first admin token");
        }
        let listener = TcpListener::bind(&config.listen)
            .await
            .with_context(|| format!("binding {}", config.listen))?;
        Ok(Application {
            listener,
            metrics,
            state,
            config,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> SocketAddr {
        self.listener.local_addr().expect("bound listener")
    }

    /// The bound port.
    pub fn port(&self) -> u16 {
        self.local_addr().port()
    }

    /// The bound address of the metrics listener, if there is one.
    pub fn metrics_addr(&self) -> Option<SocketAddr> {
        self.metrics.as_ref().and_then(|(l, _)| l.local_addr().ok())
    }

    /// The storage the server uses.
    pub fn store(&self) -> Arc<dyn Store> {
        self.state.store.clone()
    }

    /// The admission budgets (for tests and probes that watch saturation).
    pub fn admission(&self) -> http::stack::Admission {
        self.state.admission.clone()
    }

    /// Serves until `shutdown` completes, then stops accepting, lets
    /// in-flight requests finish (up to the grace period) and closes the
    /// database.
    pub async fn run_until_stopped(self, shutdown: impl Future<Output = ()>) -> anyhow::Result<()> {
        let Application {
            listener,
            metrics,
            state,
            config,
        } = self;
        let metrics_task = metrics.map(|(listener, handle)| {
            tracing::info!(address = %listener.local_addr().map_or_else(|_| "?".into(), |a| a.to_string()), "metrics listening");
            tokio::spawn(serve_metrics(listener, handle))
        });
        let store = state.store.clone();
        let events = state.events.clone();
        let (stop_deliveries, stopped) = tokio::sync::watch::channel(false);
        let deliveries = crate::app::delivery::start(
            store.clone(),
            state.web.basis,
            state.web.webhooks,
            state.deliveries.clone(),
            stopped.clone(),
        );
        let clock = crate::app::clock::start(store.clone(), state.web.status_scan, stopped);
        let router = http::router(state);
        let graceful = GracefulShutdown::new();
        let connections = Arc::new(Semaphore::new(config.max_connections));
        tracing::info!(address = %listener.local_addr()?, "accelcal listening");
        tokio::pin!(shutdown);
        loop {
            let permit = tokio::select! {
                p = connections.clone().acquire_owned() => p.expect("semaphore never closed"),
                () = &mut shutdown => break,
            };
            let (stream, peer) = tokio::select! {
                accepted = listener.accept() => match accepted {
                    Ok(a) => a,
                    Err(e) => {
                        // Out of file descriptors and the like: back off, keep serving.
                        tracing::warn!(error = %e, "accept failed");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    }
                },
                () = &mut shutdown => break,
            };
            let client = ClientAddr(peer.ip());
            let service = TowerToHyperService::new(tower::ServiceExt::map_request(
                router.clone(),
                move |mut req: axum::http::Request<hyper::body::Incoming>| {
                    req.extensions_mut().insert(client);
                    req
                },
            ));
            let mut builder = http1::Builder::new();
            builder
                .timer(TokioTimer::new())
                .header_read_timeout(config.header_timeout)
                .max_buf_size(64 * 1024);
            let conn = builder.serve_connection(TokioIo::new(ProblemIo::new(stream)), service);
            let conn = graceful.watch(conn);
            tokio::spawn(async move {
                if let Err(e) = conn.await {
                    tracing::debug!(%peer, error = %e, "connection ended with an error");
                }
                drop(permit);
            });
        }
        drop(listener);
        tracing::info!("shutting down: no new connections; finishing in-flight requests");
        // Event streams never finish by themselves: ended now, their
        // clients resume elsewhere with their last id.
        events.close();
        stop_deliveries.send_replace(true);
        if tokio::time::timeout(config.shutdown_grace, graceful.shutdown())
            .await
            .is_err()
        {
            tracing::warn!("in-flight requests did not finish within the grace period");
        }
        if let Some(task) = metrics_task {
            task.abort();
        }
        // The dispatcher and the status scan let go of the store before it
        // closes (a SQLite file is then free for the next process at once).
        let background = async {
            let _ = deliveries.await;
            let _ = clock.await;
        };
        if tokio::time::timeout(Duration::from_secs(5), background)
            .await
            .is_err()
        {
            tracing::warn!("webhook delivery or the status scan did not stop within 5 s");
        }
        store.close().await;
        tracing::info!("database closed; bye");
        Ok(())
    }
}

/// Serves `GET /metrics` (the Prometheus text format) and nothing else, and
/// keeps the recorder's histograms drained.
async fn serve_metrics(listener: TcpListener, handle: PrometheusHandle) {
    let upkeep = handle.clone();
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_secs(5));
        loop {
            tick.tick().await;
            upkeep.run_upkeep();
        }
    });
    let app = axum::Router::new().route(
        "/metrics",
        axum::routing::get(move || {
            let h = handle.clone();
            async move {
                http::metrics::before_scrape();
                (
                    [(
                        axum::http::header::CONTENT_TYPE,
                        "text/plain; version=0.0.4; charset=utf-8",
                    )],
                    h.render(),
                )
            }
        }),
    );
    if let Err(e) = axum::serve(listener, app).await {
        tracing::error!(error = %e, "the metrics listener stopped");
    }
}

/// Completes on SIGTERM or Ctrl-C.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = term => {},
    }
}
