//! Load benchmark: accelcal and the bare stack side by side, in one run, on
//! the same requests, at 1, 16 and 64 connections.
//!
//! ```text
//! cargo bench --bench load                          # SQLite, 5 s legs
//! LOAD_SECONDS=8 LOAD_ENGINES=sqlite,postgres cargo bench --bench load
//! LOAD_ROUTES=submit LOAD_CONNS=64 cargo bench --bench load   # one leg, e.g. to profile
//! LOAD_LOG=info LOAD_METRICS=1 cargo bench --bench load   # observed as deployed
//! LOAD_TOKEN=issued cargo bench --bench load   # with a token issued by the API
//! ACCELCAL_BENCH_BIN=/path/to/older/accelcal cargo bench --bench load   # another build
//! ```
//!
//! The **bare stack** is a minimal axum server (this binary, started again
//! as a child process with `ACCELCAL_LOAD_BARE=1`) answering the same routes
//! with constant bodies of the same size as accelcal's answers: the ceiling
//! this machine, runtime, HTTP stack and client reach with no application
//! work. accelcal is the release binary (`accelcal serve`), with the admin
//! token from the environment, so no token lookup; with `LOAD_TOKEN=issued`
//! every request carries instead an admin token issued by `POST /v1/tokens`,
//! looked up as a station's or a dashboard's is. Legs alternate — bare,
//! then accelcal — for every route and connection count:
//!
//! * `submit`: `POST /v1/calibrations` with the paper's Table 1 (six runs),
//!   durable (every 201 after the commit), a new `performed_at` each time;
//! * `coefficients`: `GET /v1/sensors/{id}/coefficients`;
//! * `compensate`: `POST /v1/sensors/{id}/compensate` with 100 outputs;
//! * `history`: `GET /v1/sensors/{id}/calibrations?limit=20`;
//! * `page`: `GET /ui/sensors/{id}`, the sensor's page, in a session
//!   opened by signing in with the token;
//! * `calibration`: `GET /ui/calibrations/{id}`, the latest calibration's
//!   page, in that session;
//! * `certificate`: `GET /v1/calibrations/{id}/certificate`, the latest
//!   calibration's printed certificate, a draft (not approved), so rendered
//!   on every request;
//! * `stability`: `GET /v1/sensors/{id}/stability` over the 20 stored.
//!
//! Prints req/s, p50, p99 and p99.9 latency, the ratio of accelcal's req/s
//! to the bare stack's, both servers' peak RSS during the leg and their CPU
//! time per request (user and system, all threads; for PostgreSQL, its own
//! processes' time is not included), as a
//! Markdown table for BENCHMARKS.md. Every answer's status is checked (a
//! wrong status aborts the run); timing is reported, never judged.

use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use accelcal_testkit::process as server;

use accelcal_testkit::pg;

use server::{ADMIN, Server};

/// The token every measured request carries: [`ADMIN`], or the token issued
/// by the engine's server when `LOAD_TOKEN=issued`.
static TOKEN: Mutex<Option<&'static str>> = Mutex::new(None);

fn token() -> &'static str {
    TOKEN.lock().unwrap().unwrap_or(ADMIN)
}

/// The `Cookie` header of a session opened with [`token`] (the `page`
/// route's credential), once the run has signed in.
static SESSION: Mutex<Option<&'static str>> = Mutex::new(None);

/// The routes measured.
const ROUTES: [&str; 8] = [
    "submit",
    "coefficients",
    "compensate",
    "history",
    "page",
    "calibration",
    "certificate",
    "stability",
];

/// The latest stored calibration of [`SENSOR`] (the `calibration` and
/// `certificate` routes' subject), once stored.
static LATEST: Mutex<Option<&'static str>> = Mutex::new(None);

fn latest() -> &'static str {
    LATEST.lock().unwrap().expect("stored")
}

/// Connection counts.
const CONNECTIONS: [usize; 3] = [1, 16, 64];

/// The sensor every read is about.
const SENSOR: &str = "LOAD-READ";

fn percentile(sorted: &[u32], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    f64::from(sorted[k]) / 1000.0
}

fn rss_kib(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

/// The paper's Table 1 for `sensor`, performed at the `n`-th second of 2024.
fn paper(sensor: &str, n: u64) -> Value {
    let mut v: Value = serde_json::from_str(include_str!("../examples/paper-table1.json")).unwrap();
    v["sensor_id"] = json!(sensor);
    let t = time::OffsetDateTime::from_unix_timestamp(1_704_067_200 + n as i64).unwrap();
    v["performed_at"] = json!(
        t.format(&time::format_description::well_known::Rfc3339)
            .unwrap()
    );
    v
}

fn outputs() -> Value {
    let outputs: Vec<f64> = (0..100).map(|k| -1.216 + 0.024 * f64::from(k)).collect();
    json!({ "outputs": outputs })
}

/// CPU time (user and system, every thread) `pid` has used, in seconds:
/// fields 14 and 15 of `/proc/{pid}/stat`, in clock ticks.
fn cpu_seconds(pid: u32) -> f64 {
    static TICKS: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    let hz = *TICKS.get_or_init(|| {
        Command::new("getconf")
            .arg("CLK_TCK")
            .output()
            .ok()
            .and_then(|o| String::from_utf8(o.stdout).ok())
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(100.0)
    });
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    // The command name (field 2) may hold spaces: count from after it.
    let after = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let field = |k: usize| -> f64 {
        after
            .split_whitespace()
            .nth(k - 3)
            .and_then(|v| v.parse().ok())
            .unwrap_or(0.0)
    };
    (field(14) + field(15)) / hz
}

/// One leg's figures.
struct Leg {
    rps: f64,
    p50: f64,
    p99: f64,
    p999: f64,
    rss_mib: f64,
    /// The server's CPU time per answered request, in µs: unlike req/s, it
    /// hardly depends on what else the machine runs.
    cpu_us: f64,
}

/// Sends `route` requests to `base` over `connections` connections for
/// `seconds`, sampling `pid`'s RSS.
async fn leg(base: &str, route: &'static str, connections: usize, seconds: u64, pid: u32) -> Leg {
    let stop = Arc::new(AtomicBool::new(false));
    let all = Arc::new(Mutex::new(Vec::<u32>::new()));
    let cpu_before = cpu_seconds(pid);
    static SEQUENCE: AtomicU64 = AtomicU64::new(0);
    let start = Instant::now();
    let tasks: Vec<_> = (0..connections)
        .map(|w| {
            // One client per task: one connection each, kept alive.
            let client = reqwest::Client::builder()
                .pool_max_idle_per_host(1)
                .build()
                .unwrap();
            let (stop, all, base) = (stop.clone(), all.clone(), base.to_owned());
            tokio::spawn(async move {
                let mut mine = Vec::new();
                let sensor = format!("LOAD-{w}");
                let body_out = outputs();
                while !stop.load(Ordering::Relaxed) {
                    let (req, want) = match route {
                        "submit" => {
                            let n = SEQUENCE.fetch_add(1, Ordering::Relaxed);
                            (
                                client
                                    .post(format!("{base}/v1/calibrations"))
                                    .json(&paper(&sensor, n)),
                                201,
                            )
                        }
                        "coefficients" => (
                            client.get(format!("{base}/v1/sensors/{SENSOR}/coefficients")),
                            200,
                        ),
                        "compensate" => (
                            client
                                .post(format!("{base}/v1/sensors/{SENSOR}/compensate"))
                                .json(&body_out),
                            200,
                        ),
                        "page" => (
                            client
                                .get(format!("{base}/ui/sensors/{SENSOR}"))
                                .header("cookie", SESSION.lock().unwrap().expect("signed in")),
                            200,
                        ),
                        "calibration" => (
                            client
                                .get(format!("{base}/ui/calibrations/{}", latest()))
                                .header("cookie", SESSION.lock().unwrap().expect("signed in")),
                            200,
                        ),
                        "certificate" => (
                            client.get(format!("{base}/v1/calibrations/{}/certificate", latest())),
                            200,
                        ),
                        "stability" => (
                            client.get(format!("{base}/v1/sensors/{SENSOR}/stability")),
                            200,
                        ),
                        _ => (
                            client.get(format!("{base}/v1/sensors/{SENSOR}/calibrations?limit=20")),
                            200,
                        ),
                    };
                    let req = if route == "page" || route == "calibration" {
                        req
                    } else {
                        req.bearer_auth(token())
                    };
                    let t = Instant::now();
                    let res = req.send().await.expect("request");
                    let status = res.status().as_u16();
                    let body = res.bytes().await.expect("body");
                    assert_eq!(
                        status,
                        want,
                        "{route}: {}",
                        String::from_utf8_lossy(&body[..body.len().min(300)])
                    );
                    mine.push(t.elapsed().as_micros() as u32);
                }
                all.lock().unwrap().extend(mine);
            })
        })
        .collect();
    let mut peak = 0;
    for _ in 0..seconds * 10 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        peak = peak.max(rss_kib(pid));
    }
    stop.store(true, Ordering::Relaxed);
    for t in tasks {
        t.await.unwrap();
    }
    let elapsed = start.elapsed().as_secs_f64();
    let cpu = cpu_seconds(pid) - cpu_before;
    let mut l = std::mem::take(&mut *all.lock().unwrap());
    l.sort_unstable();
    Leg {
        rps: l.len() as f64 / elapsed,
        p50: percentile(&l, 0.5),
        p99: percentile(&l, 0.99),
        p999: percentile(&l, 0.999),
        rss_mib: peak as f64 / 1024.0,
        cpu_us: cpu * 1e6 / l.len().max(1) as f64,
    }
}

/// The bare stack: the same routes, constant bodies the size of accelcal's.
async fn serve_bare(bodies: Value) {
    use axum::http::{StatusCode, header};
    use axum::routing::{get, post};
    let text = |k: &str| bytes::Bytes::from(bodies[k].as_str().unwrap().to_owned());
    let (submit, coefficients, compensate, history, page) = (
        text("submit"),
        text("coefficients"),
        text("compensate"),
        text("history"),
        text("page"),
    );
    let (calibration, certificate, stability) =
        (text("calibration"), text("certificate"), text("stability"));
    let html = || [(header::CONTENT_TYPE, "text/html; charset=utf-8")];
    let json = || [(header::CONTENT_TYPE, "application/json")];
    let app = axum::Router::new()
        .route(
            "/v1/calibrations",
            post(move |_: bytes::Bytes| async move { (StatusCode::CREATED, json(), submit) }),
        )
        .route(
            "/v1/sensors/{id}/coefficients",
            get(move || async move { (json(), coefficients) }),
        )
        .route(
            "/v1/sensors/{id}/compensate",
            post(move |_: bytes::Bytes| async move { (json(), compensate) }),
        )
        .route(
            "/v1/sensors/{id}/calibrations",
            get(move || async move { (json(), history) }),
        )
        .route(
            "/ui/sensors/{id}",
            get(move || async move { (html(), page) }),
        )
        .route(
            "/ui/calibrations/{id}",
            get(move || async move { (html(), calibration) }),
        )
        .route(
            "/v1/calibrations/{id}/certificate",
            get(move || async move { (html(), certificate) }),
        )
        .route(
            "/v1/sensors/{id}/stability",
            get(move || async move { (json(), stability) }),
        );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    println!("http://{}", listener.local_addr().unwrap());
    axum::serve(listener, app).await.unwrap();
}

/// Starts the bare stack as a child process answering with `bodies`.
fn start_bare(bodies: &Value) -> (Child, String) {
    use std::io::{BufRead, BufReader, Write};
    let mut child = Command::new(std::env::current_exe().unwrap())
        .env("ACCELCAL_LOAD_BARE", "1")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(bodies.to_string().as_bytes()).unwrap();
    drop(stdin);
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    (child, line.trim().to_owned())
}

/// One engine: accelcal and the bare stack, every route and connection count.
fn run(engine: &str, rt: &tokio::runtime::Runtime, seconds: u64) {
    let dir = tempfile::tempdir().unwrap();
    let pg = (engine == "postgres").then(pg::TestDb::create_blocking);
    let database = match (&pg, engine) {
        (Some(db), _) => db.url.clone(),
        (None, "sqlite") => dir.path().join("load.db").to_str().unwrap().to_owned(),
        (None, other) => panic!("LOAD_ENGINES: unknown engine {other}"),
    };
    // The server's log filter: by default warnings only, so the legs measure
    // the service; `LOAD_LOG=info` (a deployment's default) adds the line
    // every request writes.
    // `LOAD_METRICS=1` turns the Prometheus recorder on, as a deployment
    // scraped by Prometheus runs.
    let log = std::env::var("LOAD_LOG").unwrap_or_else(|_| "warn".into());
    let metrics: &[&str] = match std::env::var_os("LOAD_METRICS") {
        Some(_) => &["--metrics-listen", "127.0.0.1:0"],
        None => &[],
    };
    let server = Server::start_with(&database, metrics, &format!("{log},accelcal::startup=info"));
    let base = server.base.clone();
    let pid = server.child.id();

    // A stored history to read, and accelcal's answers, whose sizes the
    // bare stack copies.
    let bodies = rt.block_on(async {
        let client = reqwest::Client::new();
        if std::env::var("LOAD_TOKEN").as_deref() == Ok("issued") {
            let res = client
                .post(format!("{base}/v1/tokens"))
                .bearer_auth(ADMIN)
                .json(&json!({"role": "admin", "label": "load"}))
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 201);
            let issued: Value = res.json().await.unwrap();
            let text = issued["token"].as_str().unwrap().to_owned();
            *TOKEN.lock().unwrap() = Some(Box::leak(text.into_boxed_str()));
        }
        let mut submit = String::new();
        for n in 0..20 {
            let res = client
                .post(format!("{base}/v1/calibrations"))
                .bearer_auth(ADMIN)
                .json(&paper(SENSOR, n))
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 201);
            submit = res.text().await.unwrap();
        }
        let get = |path: String| {
            let client = client.clone();
            async move {
                let res = client.get(path).bearer_auth(ADMIN).send().await.unwrap();
                assert_eq!(res.status(), 200);
                res.text().await.unwrap()
            }
        };
        let coefficients = get(format!("{base}/v1/sensors/{SENSOR}/coefficients")).await;
        let history = get(format!("{base}/v1/sensors/{SENSOR}/calibrations?limit=20")).await;
        let res = client
            .post(format!("{base}/v1/sensors/{SENSOR}/compensate"))
            .bearer_auth(ADMIN)
            .json(&outputs())
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), 200);
        let compensate = res.text().await.unwrap();
        let session = server::sign_in(&base, token()).await;
        let page = client
            .get(format!("{base}/ui/sensors/{SENSOR}"))
            .header("cookie", &session)
            .send()
            .await
            .unwrap();
        assert_eq!(page.status(), 200);
        let page = page.text().await.unwrap();
        assert!(
            page.contains(SENSOR),
            "the sensor's page, not the sign-in form"
        );
        let id = serde_json::from_str::<Value>(&submit).unwrap()["id"]
            .as_str()
            .unwrap()
            .to_owned();
        let calibration = client
            .get(format!("{base}/ui/calibrations/{id}"))
            .header("cookie", &session)
            .send()
            .await
            .unwrap();
        assert_eq!(calibration.status(), 200);
        let calibration = calibration.text().await.unwrap();
        let certificate = get(format!("{base}/v1/calibrations/{id}/certificate")).await;
        let stability = get(format!("{base}/v1/sensors/{SENSOR}/stability")).await;
        *LATEST.lock().unwrap() = Some(Box::leak(id.into_boxed_str()));
        *SESSION.lock().unwrap() = Some(Box::leak(session.into_boxed_str()));
        json!({"submit": submit, "coefficients": coefficients, "compensate": compensate,
               "history": history, "page": page, "calibration": calibration,
               "certificate": certificate, "stability": stability})
    });
    let (mut bare, bare_base) = start_bare(&bodies);
    let bare_pid = bare.id();

    println!("\n### {engine}\n");
    println!(
        "| route | conns | accelcal req/s | p50 ms | p99 ms | p99.9 ms | bare req/s | bare p50 | bare p99 | bare p99.9 | ratio | accelcal RSS MiB | bare RSS MiB | accelcal CPU µs/req | bare CPU µs/req |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let routes = chosen("LOAD_ROUTES", &ROUTES);
    let connections = chosen("LOAD_CONNS", &CONNECTIONS);
    for &route in &routes {
        for &conns in &connections {
            let b = rt.block_on(leg(&bare_base, route, conns, seconds, bare_pid));
            let a = rt.block_on(leg(&base, route, conns, seconds, pid));
            println!(
                "| {route} | {conns} | {:.0} | {:.2} | {:.2} | {:.2} | {:.0} | {:.2} | {:.2} | {:.2} | {:.3} | {:.1} | {:.1} | {:.0} | {:.0} |",
                a.rps,
                a.p50,
                a.p99,
                a.p999,
                b.rps,
                b.p50,
                b.p99,
                b.p999,
                a.rps / b.rps,
                a.rss_mib,
                b.rss_mib,
                a.cpu_us,
                b.cpu_us
            );
        }
    }
    let _ = bare.kill();
    let _ = bare.wait();
    server.terminate();
    drop(server);
    drop(pg);
}

/// The values of `all` named in the comma-separated variable `var` (all of
/// them when it is unset); a name that is not among them aborts the run.
fn chosen<T: Copy + ToString>(var: &str, all: &[T]) -> Vec<T> {
    let Ok(list) = std::env::var(var) else {
        return all.to_vec();
    };
    list.split(',')
        .map(|name| {
            *all.iter()
                .find(|x| x.to_string() == name.trim())
                .unwrap_or_else(|| panic!("{var}: {name} is not one of the choices"))
        })
        .collect()
}

fn main() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    if std::env::var_os("ACCELCAL_LOAD_BARE").is_some() {
        let mut text = String::new();
        std::io::Read::read_to_string(&mut std::io::stdin(), &mut text).unwrap();
        rt.block_on(serve_bare(serde_json::from_str(&text).unwrap()));
        return;
    }
    let seconds: u64 = std::env::var("LOAD_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let engines = std::env::var("LOAD_ENGINES").unwrap_or_else(|_| "sqlite".into());
    println!(
        "load: {seconds} s legs, bare stack then accelcal, {} cores",
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    for engine in engines.split(',') {
        run(engine.trim(), &rt, seconds);
    }
}
