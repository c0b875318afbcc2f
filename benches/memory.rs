//! Memory per request: the server's peak resident memory (`VmHWM`) before and
//! after the largest valid submission, alone and eight at once.
//!
//! ```text
//! cargo bench --bench memory
//! ```
//!
//! The submission is the largest the limits allow in samples: 360 positions ×
//! 555 runs × 1 sample = 199 800 samples, about 2.5 MB of JSON. Then the
//! pages: that calibration's page, and the page of a sensor with 2 000
//! calibrations, one view and six at once. Prints a markdown table (pasted
//! unedited into BENCHMARKS.md). Measured, never judged.

use std::time::Instant;

use serde_json::{Value, json};

use accelcal_testkit::process as server;

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

/// Starts the tasks (at once) and measures the server's memory around
/// them: one markdown row.
async fn measured(
    pid: u32,
    label: &str,
    start_tasks: impl FnOnce() -> Vec<tokio::task::JoinHandle<usize>>,
) -> String {
    let before_rss = status_kib(pid, "VmRSS:");
    let before_peak = status_kib(pid, "VmHWM:");
    let start = Instant::now();
    let tasks = start_tasks();
    let mut answer = 0;
    for t in tasks {
        answer = t.await.unwrap();
    }
    let elapsed = start.elapsed();
    let peak = status_kib(pid, "VmHWM:");
    format!(
        "| {label} | {:.1} | {:.1} | {:.1} | {:.2} | {:.0} |",
        mib(before_rss),
        mib(peak),
        mib(peak.saturating_sub(before_peak.max(before_rss))),
        answer as f64 / 1e6,
        elapsed.as_secs_f64() * 1e3,
    )
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
            let tasks = (0..concurrent).map(|n| {
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
                tokio::spawn(async move {
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
                })
            });
            rows.push(measured(pid, label, || tasks.collect()).await);
        }
        // The pages, signed in with the admin token.
        let session = server::sign_in(&server.base, ADMIN).await;
        let history = &server.base;
        let mut lanes = Vec::new();
        for lane in 0..8 {
            let (client, base) = (client.clone(), history.clone());
            lanes.push(tokio::spawn(async move {
                for k in (lane..2000).step_by(8) {
                    let body = json!({"sensor_id": "LONG-1", "unit": "mA",
                        "performed_at": format!("{}-01-01T00:{:02}:{:02}Z", 1990 + k / 60, k % 60, k % 60),
                        "positions": [{"angle_deg": 0}, {"angle_deg": 90}, {"angle_deg": 180}, {"angle_deg": 270}],
                        "runs": (0..4).map(|j| {
                            let readings: Vec<Value> = [(0.0, 1.0), (-1.0, 0.0), (0.0, -1.0), (1.0, 0.0)]
                                .iter()
                                .enumerate()
                                .map(|(p, (ai, ap))| {
                                    let noise = 1e-6 * (f64::from(j) * 1.7 + p as f64 * 2.9 + k as f64).sin();
                                    let u = -8.4e-4 - 1.216 * ai + 6.2e-3 * ap + noise;
                                    json!([u, u + 1e-7])
                                })
                                .collect();
                            json!({"readings": readings})
                        }).collect::<Vec<_>>()});
                    let res = client
                        .post(format!("{base}/v1/calibrations"))
                        .bearer_auth(ADMIN)
                        .json(&body)
                        .send()
                        .await
                        .unwrap();
                    assert!(res.status().is_success(), "{}", res.status());
                }
            }));
        }
        for l in lanes {
            l.await.unwrap();
        }
        let largest_id = server
            .get_json("/v1/sensors/MEM-submitstored1request-0/calibrations")
            .await;
        let largest_id = largest_id["items"][0]["id"].as_str().unwrap_or_default().to_owned();
        for (label, path, concurrent) in [
            ("calibration page at the limits, 1 view", format!("/ui/calibrations/{largest_id}"), 1),
            ("calibration page at the limits, 6 at once", format!("/ui/calibrations/{largest_id}"), 6),
            ("sensor page, 2 000 calibrations, 1 view", "/ui/sensors/LONG-1".to_owned(), 1),
            ("sensor page, 2 000 calibrations, 6 at once", "/ui/sensors/LONG-1".to_owned(), 6),
        ] {
            let tasks = (0..concurrent).map(|_| {
                let (client, url, cookie) = (
                    client.clone(),
                    format!("{}{path}", server.base),
                    session.clone(),
                );
                tokio::spawn(async move {
                    let res = client.get(url).header("cookie", cookie).send().await.unwrap();
                    assert!(res.status().is_success(), "{}", res.status());
                    res.bytes().await.unwrap().len()
                })
            });
            rows.push(measured(pid, label, || tasks.collect()).await);
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
