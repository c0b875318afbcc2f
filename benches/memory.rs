//! Memory per request: the server's peak resident memory (`VmHWM`) before and
//! after the largest valid submission, alone and eight at once.
//!
//! ```text
//! cargo bench --bench memory
//! ```
//!
//! The submission is the largest the limits allow in samples: 360 positions ×
//! 555 runs × 1 sample = 199 800 samples, about 2.5 MB of JSON. Prints a
//! markdown table (pasted unedited into BENCHMARKS.md). Measured, never judged.

use std::time::Instant;

use serde_json::{Value, json};

#[path = "../tests/process/server.rs"]
mod server;

use server::{ADMIN, Server};

fn status_kib(pid: u32, field: &str) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(field))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(0)
}

/// The largest submission in samples: a linear model with a little noise.
fn largest(sensor: &str) -> Value {
    let positions: Vec<Value> = (0..360).map(|k| json!({"angle_deg": k})).collect();
    let runs: Vec<Value> = (0..555)
        .map(|j| {
            let readings: Vec<Value> = (0..360)
                .map(|k| {
                    let t = f64::from(k).to_radians();
                    let noise = 1e-6 * ((j * 360 + k) as f64 * 0.731).sin();
                    let u = -8e-4 + 1.216 * t.sin() + 6e-3 * t.cos() + noise;
                    // Nine decimals, as a station prints them.
                    json!([(u * 1e9).round() / 1e9])
                })
                .collect();
            json!({"readings": readings})
        })
        .collect();
    json!({"sensor_id": sensor, "unit": "mA", "positions": positions, "runs": runs, "batches": 2})
}

fn mib(kib: u64) -> f64 {
    kib as f64 / 1024.0
}

fn main() {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start_with(
        dir.path().join("memory.db"),
        &[],
        "warn,accelcal::startup=info",
    );
    let pid = server.child.id();
    let client = reqwest::Client::new();
    let body = serde_json::to_vec(&largest("MEM-1")).unwrap();
    println!(
        "largest submission: {} bytes of JSON, 199 800 samples",
        body.len()
    );

    let mut rows = Vec::new();
    rt.block_on(async {
        // Warm up the process (connections, pools, the first allocation arenas).
        let res = client
            .post(format!("{}/v1/fuse", server.base))
            .bearer_auth(ADMIN)
            .json(&json!({"values": {"k0": [1, 2, 3, 4]}}))
            .send()
            .await
            .unwrap();
        assert!(res.status().is_success());
        for (label, path, concurrent) in [
            ("identify, 1 request", "/v1/identify", 1),
            ("submit (stored), 1 request", "/v1/calibrations", 1),
            ("submit (stored), 8 at once", "/v1/calibrations", 8),
        ] {
            let before_rss = status_kib(pid, "VmRSS:");
            let before_peak = status_kib(pid, "VmHWM:");
            let start = Instant::now();
            let mut tasks = Vec::new();
            for n in 0..concurrent {
                let client = client.clone();
                let url = format!("{}{path}", server.base);
                let body = if path == "/v1/calibrations" {
                    serde_json::to_vec(&largest(
                        &format!("MEM-{label}-{n}").replace([' ', ',', '(', ')'], ""),
                    ))
                    .unwrap()
                } else {
                    body.clone()
                };
                tasks.push(tokio::spawn(async move {
                    let res = client
                        .post(url)
                        .bearer_auth(ADMIN)
                        .header("content-type", "application/json")
                        .body(body)
                        .send()
                        .await
                        .unwrap();
                    let status = res.status();
                    let answer = res.bytes().await.unwrap().len();
                    assert!(status.is_success(), "{status}");
                    answer
                }));
            }
            let mut answer = 0;
            for t in tasks {
                answer = t.await.unwrap();
            }
            let elapsed = start.elapsed();
            let peak = status_kib(pid, "VmHWM:");
            rows.push(format!(
                "| {label} | {:.1} | {:.1} | {:.1} | {:.1} | {:.0} |",
                mib(before_rss),
                mib(peak),
                mib(peak.saturating_sub(before_peak.max(before_rss))),
                answer as f64 / 1e6,
                elapsed.as_secs_f64() * 1e3,
            ));
        }
    });
    println!();
    println!(
        "| request | RSS before (MiB) | peak after (MiB) | peak rise (MiB) | answer (MB) | time (ms) |"
    );
    println!("|---|---|---|---|---|---|");
    for r in rows {
        println!("{r}");
    }
}
