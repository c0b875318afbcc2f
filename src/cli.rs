//! The `accelcal` command line: `serve`, `identify`, `submit`, `token create`,
//! `openapi`, `health`.
//!
//! Every setting of `serve` is a flag with an environment fallback, so the same
//! binary runs from a shell, a unit file or a container.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};

mod database;
mod dcc;
mod live;
use database::{adopt_audit, existing, migrate, verify_audit};

use crate::domain::audit::Actor;
use crate::domain::auth::Role;
use crate::domain::field::{FieldError, Invalid};
use crate::domain::limits::{DEFAULT_BODY_BUDGET_BYTES, DEFAULT_MAX_BODY_BYTES};
use crate::domain::metrology::assess_calibration;
use crate::domain::review::Basis;
use crate::domain::submission::{Media, ResultView, evaluate};
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRequest;
use crate::startup::{
    Application, Config, Laboratory, Limits, Problem, Web, openapi_document, shutdown_signal,
};
use crate::telemetry::{self, LogFormat};

/// accelcal: accelerometer calibration by tumble-test identification and
/// batch-estimation fusion.
#[derive(Debug, Parser)]
#[command(name = "accelcal", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the HTTP service (SQLite by default; PostgreSQL for several replicas).
    Serve(Box<ServeArgs>),
    /// Compute a submission file offline and print the result JSON.
    ///
    /// FILE is a JSON or CSV submission (see README), told apart by its
    /// content (`--format` to say). On bad input, prints the problem
    /// document the service would answer and exits with status 1.
    Identify {
        /// The submission file.
        file: PathBuf,
        /// The file's format, when its content should not decide.
        #[arg(long, value_enum)]
        format: Option<Format>,
    },
    /// Upload a submission file to a running service, retrying safely.
    ///
    /// The upload carries an Idempotency-Key derived from the file's content,
    /// so retries (automatic or by hand) never store it twice.
    Submit(SubmitArgs),
    /// Manage tokens directly in the database (for the first setup and
    /// recovery; the API's /v1/tokens does the same online).
    #[command(subcommand)]
    Token(TokenCommand),
    /// The audit trail (README, "Records and audit").
    #[command(subcommand)]
    Audit(AuditCommand),
    /// Digital Calibration Certificates (README, "Digital Calibration
    /// Certificates").
    #[command(subcommand)]
    Dcc(DccCommand),
    /// Print the OpenAPI document (the committed openapi.yaml is this output).
    Openapi,
    /// Copy every calibration, sensor type, token and live idempotency key
    /// from one database into another (SQLite to PostgreSQL when a
    /// deployment outgrows one machine). Stop the service first.
    Migrate {
        /// The database to copy (`sqlite:accelcal.db`, a path, or
        /// `postgres://…`).
        #[arg(long)]
        from: String,
        /// The database to copy into (it must be empty, unless
        /// --into-non-empty).
        #[arg(long)]
        to: String,
        /// Add to a target that already holds data.
        #[arg(long)]
        into_non_empty: bool,
    },
    /// Probe a running service's /readyz; exit 0 when ready (for container
    /// health checks, where no curl is installed).
    Health {
        /// Base URL of the service.
        #[arg(long, env = "ACCELCAL_URL", default_value = "http://127.0.0.1:8080")]
        url: String,
    },
}

#[derive(Debug, Args)]
struct ServeArgs {
    /// Address to listen on.
    #[arg(long, env = "ACCELCAL_LISTEN", default_value = "127.0.0.1:8080")]
    listen: String,
    /// Database: a SQLite file path (or sqlite://PATH), or postgres://… .
    #[arg(long, env = "ACCELCAL_DATABASE_URL", default_value = "accelcal.db")]
    database: String,
    /// An admin token accepted besides stored tokens: random, at least 128
    /// bits (`head -c 32 /dev/urandom | base64`); a weaker one refuses the start.
    #[arg(long, env = "ACCELCAL_ADMIN_TOKEN", hide_env_values = true)]
    admin_token: Option<String>,
    /// Largest request body in bytes (after decompression).
    #[arg(long, env = "ACCELCAL_MAX_BODY_BYTES", default_value_t = DEFAULT_MAX_BODY_BYTES)]
    max_body_bytes: usize,
    /// Bytes of request bodies received or worked on at once; beyond it new
    /// bodies are answered 503 (bounds the memory requests can take).
    #[arg(long, env = "ACCELCAL_BODY_BUDGET_BYTES", default_value_t = DEFAULT_BODY_BUDGET_BYTES)]
    body_budget_bytes: usize,
    /// Requests handled at once; beyond it the service answers 503.
    #[arg(long, env = "ACCELCAL_MAX_CONCURRENT", default_value_t = 256)]
    max_concurrent: usize,
    /// Failed authentications a client address may make in a burst before
    /// it is answered 429 (one more is forgiven every 3 s).
    #[arg(long, env = "ACCELCAL_AUTH_FAILURE_BURST", default_value_t = 20)]
    auth_failure_burst: u32,
    /// Free MiB a SQLite database's disk must keep for `/readyz` to pass.
    #[arg(long, env = "ACCELCAL_MIN_FREE_DISK_MIB", default_value_t = 64)]
    min_free_disk_mib: u64,
    /// Open connections at most.
    #[arg(long, env = "ACCELCAL_MAX_CONNECTIONS", default_value_t = 1024)]
    max_connections: usize,
    /// Seconds allowed to send a request's headers.
    #[arg(long, env = "ACCELCAL_HEADER_TIMEOUT", default_value_t = 10)]
    header_timeout: u64,
    /// Seconds allowed to send a request's body.
    #[arg(long, env = "ACCELCAL_BODY_TIMEOUT", default_value_t = 30)]
    body_timeout: u64,
    /// Seconds allowed for a whole request.
    #[arg(long, env = "ACCELCAL_REQUEST_TIMEOUT", default_value_t = 60)]
    request_timeout: u64,
    /// The service's public base URL (https://cal.example.com): certificates
    /// name themselves under it, and https marks session cookies Secure.
    #[arg(long, env = "ACCELCAL_PUBLIC_URL")]
    public_url: Option<String>,
    /// The laboratory's name, as its certificates name it.
    #[arg(long, env = "ACCELCAL_LAB_NAME")]
    lab_name: Option<String>,
    /// The laboratory's address (one line; also the place of calibration).
    #[arg(long, env = "ACCELCAL_LAB_ADDRESS")]
    lab_address: Option<String>,
    /// The laboratory's country, ISO 3166-1 alpha-2 (DE, FR, US): needed
    /// for Digital Calibration Certificates.
    #[arg(long, env = "ACCELCAL_LAB_COUNTRY")]
    lab_country: Option<String>,
    /// The laboratory's accreditation: body and number
    /// ("DAkkS D-K-12345-01-00").
    #[arg(long, env = "ACCELCAL_LAB_ACCREDITATION")]
    lab_accreditation: Option<String>,
    /// A logo for the certificates: a .png, .jpg or .svg file of at most
    /// 256 KiB, read at start.
    #[arg(long, env = "ACCELCAL_LAB_LOGO")]
    lab_logo: Option<std::path::PathBuf>,
    /// The laboratory's DCC signing key: PEM PKCS#8, RSA of at least 2048
    /// bits or ECDSA P-256, readable by the service's user only (mode
    /// 600). With --dcc-signing-cert, every DCC issued is signed; without,
    /// DCCs are issued unsigned and say so.
    #[arg(long, env = "ACCELCAL_DCC_SIGNING_KEY", requires = "dcc_signing_cert")]
    dcc_signing_key: Option<PathBuf>,
    /// The certificate of --dcc-signing-key: PEM X.509, then its chain if
    /// any; valid now.
    #[arg(long, env = "ACCELCAL_DCC_SIGNING_CERT", requires = "dcc_signing_key")]
    dcc_signing_cert: Option<PathBuf>,
    /// Serve only approved calibrations: coefficients, compensation,
    /// as-found and stability use approved calibrations only (by default
    /// every calibration not rejected or withdrawn).
    #[arg(long, env = "ACCELCAL_REQUIRE_APPROVAL")]
    require_approval: bool,
    #[command(flatten)]
    live: live::LiveArgs,
    /// Seconds a web-page session lasts after sign-in.
    #[arg(long, env = "ACCELCAL_SESSION_TTL", default_value_t = 8 * 3600)]
    session_ttl: u64,
    /// Serve Prometheus metrics at /metrics on this address (own listener;
    /// off by default).
    #[arg(long, env = "ACCELCAL_METRICS_LISTEN")]
    metrics_listen: Option<String>,
    /// Seconds in-flight requests get to finish at shutdown.
    #[arg(long, env = "ACCELCAL_SHUTDOWN_GRACE", default_value_t = 30)]
    shutdown_grace: u64,
    /// Log format.
    #[arg(long, env = "ACCELCAL_LOG_FORMAT", value_enum, default_value = "text")]
    log_format: LogFormat,
}

/// A submission file's format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Format {
    /// A JSON document.
    Json,
    /// CSV (README, "CSV layout").
    Csv,
}

#[derive(Debug, Args)]
struct SubmitArgs {
    /// The submission file (JSON or CSV, told apart by its content).
    file: PathBuf,
    /// The file's format, when its content should not decide.
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Base URL of the service.
    #[arg(long, env = "ACCELCAL_URL", default_value = "http://127.0.0.1:8080")]
    url: String,
    /// A station (or admin) token.
    #[arg(long, env = "ACCELCAL_TOKEN", hide_env_values = true)]
    token: String,
    /// Attempts in all before giving up.
    #[arg(long, default_value_t = 6)]
    attempts: u32,
}

#[derive(Debug, Subcommand)]
enum AuditCommand {
    /// Recompute the audit trail's hash chain, and check every row the
    /// service serves or acts on — calibrations and every served column,
    /// signatures, issued certificates, standards, customers, items, sensor
    /// types, tokens, nonconformities, sensors — against it; print the head
    /// (keep it elsewhere) and the rows checked, and exit 0, or name the
    /// first entry that does not hold, or every row that does not (edited,
    /// inserted or deleted behind the service's back, or never audited), and
    /// exit 1.
    Verify {
        /// Database: a SQLite file path (or sqlite://PATH), or postgres://… .
        #[arg(long, env = "ACCELCAL_DATABASE_URL", default_value = "accelcal.db")]
        database: String,
    },
    /// Record in the trail, by the operator running it, every row `verify`
    /// finds without any audit entry — rows a database held before its
    /// trail — with the SHA-256 of its content, so that `verify` covers them
    /// from then on; print what it adopted. Refused when the chain is broken
    /// or any row differs from its entries: an edit is never adopted.
    Adopt {
        /// Database: a SQLite file path (or sqlite://PATH), or postgres://… .
        #[arg(long, env = "ACCELCAL_DATABASE_URL", default_value = "accelcal.db")]
        database: String,
    },
}

#[derive(Debug, Subcommand)]
enum DccCommand {
    /// Check a DCC's XML Signature as a receiver would: the structure (one
    /// signature, the root's last child, over the whole document), the
    /// signature value and both digests, the signed signing time and
    /// certificate; print who signed it and when, and exit 0, or say why
    /// not and exit 1 (2: the file cannot be read or is not a DCC).
    Verify {
        /// The DCC file.
        file: PathBuf,
        /// Trust only this certificate (PEM; repeat for several, e.g. the
        /// laboratory's current and previous). Without it, the certificate
        /// the file embeds is used: integrity and the signer's name, not
        /// whether to trust the signer.
        #[arg(long)]
        cert: Vec<PathBuf>,
    },
}

#[derive(Debug, Subcommand)]
enum TokenCommand {
    /// Create a token and print it (once) as JSON.
    Create {
        /// reader, station, reviewer or admin.
        #[arg(long)]
        role: String,
        /// Bind a station token to this station id.
        #[arg(long)]
        station: Option<String>,
        /// A label to recognise the token by.
        #[arg(long)]
        label: Option<String>,
        /// The name of the person who holds the token (what their
        /// signatures print).
        #[arg(long)]
        holder: Option<String>,
        /// Database: a SQLite file path (or sqlite://PATH), or postgres://… .
        #[arg(long, env = "ACCELCAL_DATABASE_URL", default_value = "accelcal.db")]
        database: String,
        /// Create the SQLite database when there is none at --database
        /// (without it, a missing file is an error: a wrong directory would
        /// otherwise get a new, empty database whose token no server knows).
        #[arg(long)]
        create: bool,
    },
}

/// Parses the command line and runs it.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Identify { file, format } => identify(&file, format),
        Command::Serve(args) => {
            // Held until the server has stopped: dropping it writes what is queued.
            let _logs = telemetry::init(args.log_format);
            run_async(serve(*args))
        }
        Command::Submit(args) => {
            let _logs = telemetry::init(LogFormat::Text);
            run_async(submit(args))
        }
        Command::Token(TokenCommand::Create {
            role,
            station,
            label,
            holder,
            database,
            create,
        }) => match existing(&database, create) {
            Ok(()) => run_async(create_token(
                role,
                TokenFlags {
                    station,
                    label,
                    holder,
                },
                database,
            )),
            Err(e) => {
                eprintln!("accelcal: {e}");
                ExitCode::from(2)
            }
        },
        Command::Health { url } => run_async(health(url)),
        Command::Migrate {
            from,
            to,
            into_non_empty,
        } => run_async(migrate(from, to, into_non_empty)),
        Command::Audit(AuditCommand::Verify { database }) => run_async(verify_audit(database)),
        Command::Audit(AuditCommand::Adopt { database }) => run_async(adopt_audit(database)),
        Command::Dcc(DccCommand::Verify { file, cert }) => dcc::verify_file(&file, &cert),
        Command::Openapi => out(&openapi_document()),
    }
}

async fn health(url: String) -> anyhow::Result<ExitCode> {
    let client = reqwest::Client::builder()
        .timeout(Duration::from_secs(5))
        .build()?;
    let res = client
        .get(format!("{}/readyz", url.trim_end_matches('/')))
        .send()
        .await;
    Ok(match res {
        Ok(r) if r.status().is_success() => ExitCode::SUCCESS,
        Ok(r) => {
            eprintln!("accelcal: not ready: {}", r.status());
            ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("accelcal: no answer: {e}");
            ExitCode::FAILURE
        }
    })
}

fn run_async(f: impl std::future::Future<Output = anyhow::Result<ExitCode>>) -> ExitCode {
    let runtime = match tokio::runtime::Runtime::new() {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("accelcal: cannot start the runtime: {e}");
            return ExitCode::from(2);
        }
    };
    match runtime.block_on(f) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("accelcal: {e:#}");
            ExitCode::from(2)
        }
    }
}

async fn serve(a: ServeArgs) -> anyhow::Result<ExitCode> {
    let config = Config {
        listen: a.listen,
        database: a.database,
        admin_token: a.admin_token.filter(|t| !t.is_empty()),
        limits: Limits {
            max_body_bytes: a.max_body_bytes,
            body_budget_bytes: a.body_budget_bytes.max(a.max_body_bytes),
            body_timeout: Duration::from_secs(a.body_timeout),
            request_timeout: Duration::from_secs(a.request_timeout),
            max_concurrent: a.max_concurrent.max(1),
            auth_failure_burst: a.auth_failure_burst.max(1),
            ..Limits::default()
        },
        header_timeout: Duration::from_secs(a.header_timeout),
        max_connections: a.max_connections.max(1),
        shutdown_grace: Duration::from_secs(a.shutdown_grace),
        web: Web {
            public_url: a.public_url.filter(|u| !u.is_empty()),
            session_ttl: Duration::from_secs(a.session_ttl.max(1)),
            events_heartbeat: a.live.heartbeat(),
            events_poll: a.live.poll(),
            webhooks: a.live.webhooks()?,
            status_scan: a.live.status_scan()?,
            laboratory: Laboratory {
                name: a.lab_name.filter(|n| !n.is_empty()),
                address: a.lab_address.filter(|n| !n.is_empty()),
                country: a
                    .lab_country
                    .filter(|c| !c.is_empty())
                    .map(|c| Laboratory::country_from(&c))
                    .transpose()
                    .map_err(|e| anyhow::anyhow!("--lab-country {e}"))?,
                accreditation: a.lab_accreditation.filter(|n| !n.is_empty()),
                logo: a
                    .lab_logo
                    .map(|p| Laboratory::logo_from(&p))
                    .transpose()
                    .map_err(|e| anyhow::anyhow!("--lab-logo {e}"))?,
            },
            basis: if a.require_approval {
                Basis::ApprovedOnly
            } else {
                Basis::NotRejected
            },
            dcc_signer: match (&a.dcc_signing_key, &a.dcc_signing_cert) {
                (Some(key), Some(cert)) => {
                    Some(std::sync::Arc::new(crate::startup::dcc_signer(key, cert)?))
                }
                _ => {
                    tracing::info!(
                        "DCCs are issued unsigned (no --dcc-signing-key and --dcc-signing-cert)"
                    );
                    None
                }
            },
        },
        metrics_listen: a.metrics_listen.filter(|m| !m.is_empty()),
        min_free_disk_bytes: a.min_free_disk_mib.saturating_mul(1024 * 1024),
    };
    let app = Application::build(config).await?;
    app.run_until_stopped(shutdown_signal()).await?;
    Ok(ExitCode::SUCCESS)
}

/// A token request's problems in the command line's terms (`--station …`).
fn flags(invalid: &Invalid) -> String {
    let flag = |e: &FieldError| match e.pointer.as_str() {
        "/station_id" => "--station",
        "/label" => "--label",
        "/holder" => "--holder",
        _ => "--role",
    };
    invalid
        .errors
        .iter()
        .map(|e| format!("{} {}", flag(e), e.detail))
        .collect::<Vec<_>>()
        .join("; ")
}

/// Writes `text` to standard output, ending with a line break. A reader that went
/// away (`accelcal identify … | head`) ends the command quietly, as any
/// Unix filter does; another write error is an error.
fn out(text: &str) -> ExitCode {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    let end = if text.ends_with('\n') { "" } else { "\n" };
    match write!(stdout, "{text}{end}").and_then(|()| stdout.flush()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("accelcal: cannot write the output: {e}");
            ExitCode::from(2)
        }
    }
}

/// The format of a submission: `format` when given, else by content — a
/// JSON submission is an object, so a body whose first character (after
/// white space and a byte-order mark) is `{` is JSON, anything else CSV.
fn media_of(bytes: &[u8], format: Option<Format>) -> (Media, &'static str) {
    let json = match format {
        Some(f) => f == Format::Json,
        None => {
            let text = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
            text.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{')
        }
    };
    if json {
        (Media::Json, "application/json")
    } else {
        (Media::Csv, "text/csv")
    }
}

fn identify(file: &Path, format: Option<Format>) -> ExitCode {
    let bytes = match std::fs::read(file) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("accelcal: cannot read {}: {e}", file.display());
            return ExitCode::from(2);
        }
    };
    let now = Timestamp::now();
    match evaluate(media_of(&bytes, format).0, &bytes, now) {
        Ok(e) => {
            // Offline: no sensor type, no previous calibration.
            let performed_at = e.submission.performed_at.unwrap_or(now);
            let metrology = match assess_calibration(&e, performed_at, None, None) {
                Ok(m) => m,
                Err(invalid) => {
                    let problem = Problem::from(invalid);
                    eprintln!("{}", String::from_utf8_lossy(&problem.to_json(None)));
                    return ExitCode::FAILURE;
                }
            };
            let station = e.submission.station_id.as_deref();
            let view = ResultView::new(&e, None, station, now, None, &metrology);
            match serde_json::to_string_pretty(&view) {
                Ok(text) => out(&text),
                Err(e) => {
                    eprintln!("accelcal: {e}");
                    ExitCode::from(2)
                }
            }
        }
        Err(refused) => {
            // The problem document the service would answer.
            let problem = Problem::from(refused);
            eprintln!("{}", String::from_utf8_lossy(&problem.to_json(None)));
            ExitCode::FAILURE
        }
    }
}

async fn submit(a: SubmitArgs) -> anyhow::Result<ExitCode> {
    let body = std::fs::read(&a.file)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", a.file.display()))?;
    let content_type = media_of(&body, a.format).1;
    let upload = crate::client::Upload {
        url: a.url,
        token: a.token,
        body,
        content_type,
        attempts: a.attempts.max(1),
        backoff: Duration::from_millis(500),
        on_retry: Some(std::sync::Arc::new(|r: &crate::client::Retry| {
            eprintln!(
                "accelcal: attempt {} failed ({}); retrying in {:.1} s",
                r.attempt,
                r.reason,
                r.wait.as_secs_f64()
            );
        })),
    };
    let answer = crate::client::submit(&upload).await?;
    if answer.status.is_success() {
        Ok(out(&answer.body))
    } else {
        eprintln!("{}", answer.body);
        Ok(ExitCode::FAILURE)
    }
}

/// `accelcal token create`'s optional flags.
struct TokenFlags {
    station: Option<String>,
    label: Option<String>,
    holder: Option<String>,
}

async fn create_token(
    role: String,
    flags_: TokenFlags,
    database: String,
) -> anyhow::Result<ExitCode> {
    let role = Role::parse(&role)
        .ok_or_else(|| anyhow::anyhow!("--role must be reader, station, reviewer or admin"))?;
    let request = TokenRequest {
        role,
        station_id: flags_.station,
        label: flags_.label,
        holder: flags_.holder,
    }
    .check()
    .map_err(|invalid| anyhow::anyhow!("{}", flags(&invalid)))?;
    let lab = crate::app::Lab::offline(crate::store::open(&database).await?);
    let created = crate::app::tokens::create(&lab, Actor::command_line(), request).await;
    lab.store.close().await;
    let created = created?;
    Ok(out(&serde_json::to_string_pretty(&created)?))
}
