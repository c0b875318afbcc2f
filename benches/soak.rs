//! Load and soak benchmark: the machine's bare-stack figure, then accelcal
//! under a bounded soak of mixed traffic from a loopback load generator.
//!
//! ```text
//! cargo bench --bench soak                      # 60 s soak, release build
//! cargo test --bench soak                       # the same in the test profile (CI)
//! SOAK_SECONDS=20 SOAK_WORKERS=32 cargo bench --bench soak
//! SOAK_ENGINES=sqlite,postgres cargo bench --bench soak   # both, one run
//! ```
//!
//! With `postgres` among `SOAK_ENGINES`, the soak runs again on a fresh
//! database of the server `ACCELCAL_TEST_POSTGRES_URL` names (default: the
//! local one), after SQLite, in the same process and run.
//!
//! 1. **Bare stack**: a minimal axum handler returning a constant JSON body,
//!    in this process, loaded by the same client for 5 s: the ceiling this
//!    machine, runtime and client reach with no application work.
//! 2. **accelcal `/healthz`** for 5 s: the same, through accelcal's middleware.
//! 3. **Soak**: `SOAK_SECONDS` (default 60) of mixed traffic — submissions with
//!    idempotency keys and their retries, coefficient and history reads,
//!    compensation, identify, invalid bodies — plus clients that send bodies
//!    too slowly (408) or declare them too large (413). The server's RSS is
//!    sampled every second.
//!
//! Exits non-zero when any answer is not the one its request calls for, or
//! when memory is not flat: the mean RSS of the last 10 s may exceed that of
//! seconds 10–20 by at most 20 % + 8 MiB. Timing is reported, never judged.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use accelcal_testkit::process as server;

use accelcal_testkit::pg;

use server::{ADMIN, Server};

#[derive(Default)]
struct Stats {
    latencies: BTreeMap<&'static str, Vec<u32>>,
    errors: Vec<String>,
}

impl Stats {
    fn record(&mut self, kind: &'static str, micros: u32) {
        self.latencies.entry(kind).or_default().push(micros);
    }
}

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

fn submission(sensor: &str, n: u64) -> Value {
    let runs: Vec<Value> = (0..6u64)
        .map(|j| {
            let e = |p: u64| 1e-6 * (n as f64 * 0.37 + j as f64 * 1.3 + p as f64 * 2.1).sin();
            json!({"readings": [[0.0062 + e(0), 0.0061 + e(0)], [1.216 + e(1), 1.2161 + e(1)],
                                [-0.0062 + e(2), -0.0063 + e(2)], [-1.216 + e(3), -1.2159 + e(3)]]})
        })
        .collect();
    json!({
        "sensor_id": sensor,
        "performed_at": format!("2025-{:02}-{:02}T00:00:00Z", 1 + n % 12, 1 + n % 28),
        "unit": "mA",
        "positions": [{"angle_deg": 0}, {"angle_deg": 90}, {"angle_deg": 180}, {"angle_deg": 270}],
        "runs": runs,
    })
}

/// Hits `url` with `workers` clients for `seconds`; returns requests/s and p50/p99 ms.
async fn plain_load(url: String, workers: usize, seconds: u64) -> (f64, f64, f64) {
    let client = reqwest::Client::new();
    let stop = Arc::new(AtomicBool::new(false));
    let all = Arc::new(Mutex::new(Vec::<u32>::new()));
    let start = Instant::now();
    let tasks: Vec<_> = (0..workers)
        .map(|_| {
            let (client, url, stop, all) = (client.clone(), url.clone(), stop.clone(), all.clone());
            tokio::spawn(async move {
                let mut mine = Vec::new();
                while !stop.load(Ordering::Relaxed) {
                    let t = Instant::now();
                    let res = client.get(&url).send().await.expect("bare request");
                    assert!(res.status().is_success());
                    res.bytes().await.unwrap();
                    mine.push(t.elapsed().as_micros() as u32);
                }
                all.lock().unwrap().extend(mine);
            })
        })
        .collect();
    tokio::time::sleep(Duration::from_secs(seconds)).await;
    stop.store(true, Ordering::Relaxed);
    for t in tasks {
        t.await.unwrap();
    }
    let elapsed = start.elapsed().as_secs_f64();
    let mut l = std::mem::take(&mut *all.lock().unwrap());
    l.sort_unstable();
    (
        l.len() as f64 / elapsed,
        percentile(&l, 0.5),
        percentile(&l, 0.99),
    )
}

async fn bare_stack(workers: usize) -> (f64, f64, f64) {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let app = axum::Router::new().route(
        "/",
        axum::routing::get(|| async { axum::Json(json!({"status": "ok"})) }),
    );
    let server = tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    let out = plain_load(format!("http://{addr}/"), workers, 5).await;
    server.abort();
    out
}

struct Soak {
    base: String,
    client: reqwest::Client,
    stats: Arc<Mutex<Stats>>,
    stop: Arc<AtomicBool>,
}

impl Soak {
    /// Sends a request expecting one status; on it, returns the JSON body
    /// and the headers, else records the answer as unexpected.
    async fn call(
        &self,
        kind: &'static str,
        req: reqwest::RequestBuilder,
        want: u16,
    ) -> Option<(Value, reqwest::header::HeaderMap)> {
        let t = Instant::now();
        let res = req.bearer_auth(ADMIN).send().await;
        let micros = t.elapsed().as_micros() as u32;
        match res {
            Ok(r) if r.status().as_u16() == want => {
                let headers = r.headers().clone();
                let body = r.bytes().await.ok()?;
                self.stats.lock().unwrap().record(kind, micros);
                Some((
                    serde_json::from_slice(&body).unwrap_or(Value::Null),
                    headers,
                ))
            }
            Ok(r) => {
                let s = r.status();
                let text = r.text().await.unwrap_or_default();
                let text: String = text.chars().take(200).collect();
                self.stats
                    .lock()
                    .unwrap()
                    .errors
                    .push(format!("{kind}: {s} {text}"));
                None
            }
            Err(e) => {
                self.stats
                    .lock()
                    .unwrap()
                    .errors
                    .push(format!("{kind}: {e}"));
                None
            }
        }
    }

    /// Records a wrong value (the status was right, the content not).
    fn wrong(&self, kind: &str, what: String) {
        self.stats
            .lock()
            .unwrap()
            .errors
            .push(format!("{kind}: {what}"));
    }

    /// One client on its own sensor: it knows every calibration it stored,
    /// so every answer is checked against what it must be — the latest
    /// coefficients, the history's order and size, compensation against the
    /// model inverted by hand, a retry's replay of the same id, and 404 only
    /// while nothing is stored yet.
    async fn worker(self: Arc<Self>, w: u64) {
        let mut n = w * 1_000_000;
        let mut last: Option<(String, Value, String)> = None;
        // (performed_at, id, fused coefficients) of every stored calibration.
        let mut stored: Vec<(String, String, Value)> = Vec::new();
        let sensor = format!("SOAK-{w}");
        let url = |p: &str| format!("{}{p}", self.base);
        let latest = |stored: &[(String, String, Value)]| {
            stored
                .iter()
                .max_by(|a, b| (&a.0, &a.1).cmp(&(&b.0, &b.1)))
                .cloned()
        };
        while !self.stop.load(Ordering::Relaxed) {
            n += 1;
            let nothing = stored.is_empty();
            match n % 20 {
                0..=4 => {
                    let body = submission(&sensor, n);
                    let key = format!("soak-{n}");
                    let req = self
                        .client
                        .post(url("/v1/calibrations"))
                        .header("idempotency-key", &key)
                        .json(&body);
                    if let Some((r, h)) = self.call("submit", req, 201).await {
                        if h.contains_key("idempotent-replayed") {
                            self.wrong("submit", "a first request was answered as a replay".into());
                        }
                        let id = r["id"].as_str().unwrap_or_default().to_owned();
                        let at = r["performed_at"].as_str().unwrap_or_default().to_owned();
                        stored.push((at, id.clone(), r["fused"]["coefficients"].clone()));
                        last = Some((key, body, id));
                    }
                }
                5 => {
                    if let Some((key, body, id)) = &last {
                        let req = self
                            .client
                            .post(url("/v1/calibrations"))
                            .header("idempotency-key", key)
                            .json(body);
                        if let Some((r, h)) = self.call("submit retry", req, 201).await {
                            if h.get("idempotent-replayed").is_none_or(|v| v != "true") {
                                self.wrong("submit retry", "no Idempotent-Replayed: true".into());
                            }
                            if r["id"] != json!(id) {
                                self.wrong(
                                    "submit retry",
                                    format!("id {} instead of {id}", r["id"]),
                                );
                            }
                        }
                    }
                }
                6..=9 => {
                    let req = self
                        .client
                        .get(url(&format!("/v1/sensors/{sensor}/coefficients")));
                    let want = if nothing { 404 } else { 200 };
                    if let (Some((r, _)), Some((_, id, coefficients))) =
                        (self.call("coefficients", req, want).await, latest(&stored))
                        && (r["calibration_id"] != json!(id) || r["coefficients"] != coefficients)
                    {
                        self.wrong(
                            "coefficients",
                            format!("{r} is not the latest stored ({id})"),
                        );
                    }
                }
                10 | 11 => {
                    let req = self
                        .client
                        .get(url(&format!("/v1/sensors/{sensor}/calibrations?limit=20")));
                    let want = if nothing { 404 } else { 200 };
                    if let (Some((r, _)), Some((_, id, _))) =
                        (self.call("history", req, want).await, latest(&stored))
                    {
                        let items = r["items"].as_array().map_or(0, Vec::len);
                        if items != stored.len().min(20) || r["items"][0]["id"] != json!(id) {
                            self.wrong(
                                "history",
                                format!("{items} items, first {}", r["items"][0]["id"]),
                            );
                        }
                    }
                }
                12 => {
                    let req = self.client.get(url("/v1/sensors?limit=100"));
                    self.call("sensors", req, 200).await;
                }
                13 | 14 => {
                    let outputs: Vec<f64> =
                        (0..100).map(|k| -1.216 + 0.024 * f64::from(k)).collect();
                    let req = self
                        .client
                        .post(url(&format!("/v1/sensors/{sensor}/compensate")))
                        .json(&json!({"outputs": outputs}));
                    let want = if nothing { 404 } else { 200 };
                    if let (Some((r, _)), Some((_, _, k))) =
                        (self.call("compensate", req, want).await, latest(&stored))
                    {
                        // U = k0 + ki·a_i + kp·a_p with a_p = 0, inverted by hand.
                        let (k0, ki) = (
                            k["k0"].as_f64().unwrap_or(0.0),
                            k["ki"].as_f64().unwrap_or(1.0),
                        );
                        let ok = outputs.iter().enumerate().all(|(j, u)| {
                            r["a_i"][j]
                                .as_f64()
                                .is_some_and(|a| (a - (u - k0) / ki).abs() < 1e-12)
                        });
                        if !ok {
                            self.wrong("compensate", format!("{}", r["a_i"][0]));
                        }
                    }
                }
                15 | 16 => {
                    let req = self
                        .client
                        .post(url("/v1/identify"))
                        .json(&submission(&sensor, n));
                    if let Some((r, _)) = self.call("identify", req, 200).await
                        && (r["sensor_id"] != json!(sensor)
                            || r.get("id").is_some()
                            || r["runs"].as_array().map_or(0, Vec::len) != 6)
                    {
                        self.wrong("identify", "not the result of the request".into());
                    }
                }
                17 => {
                    let mut bad = submission(&sensor, n);
                    bad["batchs"] = json!(2);
                    let req = self.client.post(url("/v1/calibrations")).json(&bad);
                    if let Some((r, _)) = self.call("invalid (422)", req, 422).await
                        && r["errors"][0]["pointer"] != "/batchs"
                    {
                        self.wrong("invalid (422)", format!("{r}"));
                    }
                }
                18 => {
                    let values = [1.0, 1.1, 0.9, 1.05, 0.97, 1.02];
                    let req = self
                        .client
                        .post(url("/v1/fuse"))
                        .json(&json!({"values": {"k0": values}}));
                    if let Some((r, _)) = self.call("fuse", req, 200).await {
                        let mean = values.iter().sum::<f64>() / 6.0;
                        if r["mean"]["coefficients"]["k0"]
                            .as_f64()
                            .is_none_or(|m| (m - mean).abs() > 1e-15)
                        {
                            self.wrong("fuse", format!("{}", r["mean"]));
                        }
                    }
                }
                _ => {
                    let req = self.client.get(url("/healthz"));
                    self.call("healthz", req, 200).await;
                }
            }
        }
    }

    /// Clients that misbehave: bodies declared too large, bodies trickled
    /// too slowly. Each must get its 413 or 408 and its connection closed.
    async fn hostile(self: Arc<Self>, slow: bool) {
        let addr = self.base.trim_start_matches("http://").to_owned();
        while !self.stop.load(Ordering::Relaxed) {
            let t = Instant::now();
            let Ok(mut s) = tokio::net::TcpStream::connect(&addr).await else {
                self.stats
                    .lock()
                    .unwrap()
                    .errors
                    .push("hostile: connect failed".into());
                continue;
            };
            let (len, kind, want) = if slow {
                (2000, "slow body (408)", "HTTP/1.1 408")
            } else {
                (100_000_000, "oversized (413)", "HTTP/1.1 413")
            };
            let head = format!(
                "POST /v1/calibrations HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n\
                 Content-Type: application/json\r\nContent-Length: {len}\r\nConnection: close\r\n\r\n{{"
            );
            if s.write_all(head.as_bytes()).await.is_err() {
                continue;
            }
            let mut answer = Vec::new();
            if slow {
                // One byte every 100 ms, until the server gives up on us.
                loop {
                    tokio::select! {
                        r = s.read_to_end(&mut answer) => { let _ = r; break; }
                        () = tokio::time::sleep(Duration::from_millis(100)) => {
                            if s.write_all(b" ").await.is_err() { let _ = s.read_to_end(&mut answer).await; break; }
                        }
                    }
                }
            } else {
                let _ =
                    tokio::time::timeout(Duration::from_secs(10), s.read_to_end(&mut answer)).await;
            }
            let text = String::from_utf8_lossy(&answer);
            {
                let mut st = self.stats.lock().unwrap();
                if text.starts_with(want) {
                    st.record(kind, t.elapsed().as_micros() as u32);
                } else {
                    st.errors.push(format!(
                        "{kind}: {}",
                        text.lines().next().unwrap_or("no answer")
                    ));
                }
            }
            if !slow {
                // A few oversized uploads a second, not a flood.
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    }
}

fn main() {
    let seconds: u64 = std::env::var("SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60)
        .max(30);
    let workers: usize = std::env::var("SOAK_WORKERS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(16);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();

    println!(
        "soak: {workers} workers, {seconds} s, {} cores",
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    let (bare_rps, bare_p50, bare_p99) = rt.block_on(bare_stack(workers));

    let engines = std::env::var("SOAK_ENGINES").unwrap_or_else(|_| "sqlite".into());
    let mut failed = false;
    for engine in engines.split(',').map(str::trim) {
        println!();
        println!("### {engine}");
        failed |= !soak_on(
            engine,
            &rt,
            seconds,
            workers,
            (bare_rps, bare_p50, bare_p99),
        );
    }
    if failed {
        std::process::exit(1);
    }
    println!("soak: ok (no unexpected answer, memory flat)");
}

/// The soak on one engine; whether it passed.
fn soak_on(
    engine: &str,
    rt: &tokio::runtime::Runtime,
    seconds: u64,
    workers: usize,
    (bare_rps, bare_p50, bare_p99): (f64, f64, f64),
) -> bool {
    let dir = tempfile::tempdir().unwrap();
    let pg = (engine == "postgres").then(pg::TestDb::create_blocking);
    let database = match (&pg, engine) {
        (Some(db), _) => db.url.clone(),
        (None, "sqlite") => dir.path().join("soak.db").to_str().unwrap().to_owned(),
        (None, other) => panic!("SOAK_ENGINES: unknown engine {other}"),
    };
    let mut server = Server::start_with(
        &database,
        &["--body-timeout", "3"],
        "warn,accelcal::startup=info",
    );
    let pid = server.child.id();
    let base = server.base.clone();

    let (h_rps, h_p50, h_p99) = rt.block_on(plain_load(format!("{base}/healthz"), workers, 5));

    let soak = Arc::new(Soak {
        base: base.clone(),
        client: reqwest::Client::new(),
        stats: Arc::new(Mutex::new(Stats::default())),
        stop: Arc::new(AtomicBool::new(false)),
    });
    let mut rss = Vec::new();
    let start = Instant::now();
    rt.block_on(async {
        let mut tasks: Vec<_> = (0..workers as u64)
            .map(|w| tokio::spawn(soak.clone().worker(w)))
            .collect();
        tasks.push(tokio::spawn(soak.clone().hostile(true)));
        tasks.push(tokio::spawn(soak.clone().hostile(true)));
        tasks.push(tokio::spawn(soak.clone().hostile(false)));
        for _ in 0..seconds {
            tokio::time::sleep(Duration::from_secs(1)).await;
            rss.push(rss_kib(pid));
        }
        soak.stop.store(true, Ordering::Relaxed);
        for t in tasks {
            t.await.unwrap();
        }
    });
    let elapsed = start.elapsed().as_secs_f64();
    server.terminate();
    let exit = server.child.wait().unwrap();
    let server_errors: Vec<String> = server
        .log
        .lock()
        .unwrap()
        .iter()
        .filter(|line| {
            let v: Value = serde_json::from_str(line).unwrap_or_default();
            v["level"] == "ERROR" || v["status"].as_u64().is_some_and(|s| s >= 500)
        })
        .cloned()
        .collect();

    let mut stats = soak.stats.lock().unwrap();
    let total: usize = stats.latencies.values().map(Vec::len).sum();
    let unexpected = stats.errors.len();
    // Markdown, to paste unedited into BENCHMARKS.md.
    println!();
    println!("| | req/s | p50 ms | p99 ms |");
    println!("|---|---|---|---|");
    println!(
        "| bare stack (axum, constant JSON, same client) | {bare_rps:.0} | {bare_p50:.2} | {bare_p99:.2} |"
    );
    println!(
        "| accelcal `GET /healthz` (full middleware) | {h_rps:.0} | {h_p50:.2} | {h_p99:.2} |"
    );
    println!(
        "| soak, every kind together | {:.0} | | |",
        total as f64 / elapsed
    );
    println!();
    println!("| kind (soak, {seconds} s, {workers} workers) | count | p50 ms | p99 ms |");
    println!("|---|---|---|---|");
    for (kind, l) in stats.latencies.iter_mut() {
        l.sort_unstable();
        println!(
            "| {kind} | {} | {:.2} | {:.2} |",
            l.len(),
            percentile(l, 0.5),
            percentile(l, 0.99)
        );
    }
    println!("| **all answers checked** | **{total}** | | |");
    println!("| unexpected (wrong status or value) | {unexpected} | | |");
    let mean = |w: &[u64]| w.iter().sum::<u64>() as f64 / w.len().max(1) as f64 / 1024.0;
    let early = mean(&rss[10..20]);
    let late = mean(&rss[rss.len() - 10..]);
    let max = *rss.iter().max().unwrap() as f64 / 1024.0;
    println!();
    println!(
        "Server RSS: mean {early:.1} MiB over seconds 10–20, {late:.1} MiB over the last 10 s, maximum {max:.1} MiB. Exit on SIGTERM: {exit}."
    );

    let mut failed = false;
    if !stats.errors.is_empty() || !server_errors.is_empty() {
        failed = true;
        println!(
            "FAIL: {} unexpected answers, {} server errors",
            stats.errors.len(),
            server_errors.len()
        );
        for e in stats.errors.iter().chain(server_errors.iter()).take(20) {
            println!("  {e}");
        }
    }
    if late > early * 1.2 + 8.0 {
        failed = true;
        println!("FAIL: memory grew from {early:.1} MiB to {late:.1} MiB");
    }
    if !exit.success() {
        failed = true;
        println!("FAIL: the server did not exit cleanly");
    }
    !failed
}
