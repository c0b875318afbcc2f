//! Memory per request: the server's peak resident memory (`VmHWM`) before and
//! after the largest valid submission, alone and eight at once.
//!
//! ```text
//! cargo bench --bench memory
//! ```
//!
//! Two largest submissions: the largest in samples (8 positions × 20 runs ×
//! 12 500 samples = 2 000 000, long static windows, about 26 MB of JSON),
//! sent plain and gzip-compressed, alone and two at once (one token's
//! share of the body budget); and the largest in cells (360 positions ×
//! 1 000 runs × 1 sample, whose answer is the largest), alone and eight at
//! once. Then the pages: the latter calibration's page, and the page of a
//! sensor with 2 000 calibrations, one view and six at once. Prints a
//! markdown table (pasted unedited into BENCHMARKS.md). Measured, never
//! judged.

use std::time::Instant;

use serde_json::{Value, json};

use accelcal_testkit::gzip;
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

/// A submission of `positions` equally spaced angles × `runs` runs ×
/// `samples` samples each: a linear model with a little noise, nine
/// decimals as a station prints them.
fn tumble(sensor: &str, positions: u32, runs: u32, samples: u32) -> Vec<u8> {
    let step = 360 / positions;
    let angles: Vec<Value> = (0..positions)
        .map(|k| json!({"angle_deg": k * step}))
        .collect();
    let runs: Vec<Value> = (0..runs)
        .map(|j| {
            let readings: Vec<Value> = (0..positions)
                .map(|k| {
                    let t = f64::from(k * step).to_radians();
                    let u = -8e-4 + 1.216 * t.sin() + 6e-3 * t.cos();
                    let window: Vec<f64> = (0..samples)
                        .map(|s| {
                            let n = f64::from((j * positions + k) * samples + s);
                            ((u + 1e-6 * (n * 0.731).sin()) * 1e9).round() / 1e9
                        })
                        .collect();
                    json!(window)
                })
                .collect();
            json!({"readings": readings})
        })
        .collect();
    serde_json::to_vec(
        &json!({"sensor_id": sensor, "unit": "mA", "positions": angles,
        "runs": runs, "batches": 2}),
    )
    .unwrap()
}

/// The largest submission in samples: 2 000 000 in long windows.
fn most_samples(sensor: &str) -> Vec<u8> {
    tumble(sensor, 8, 20, 12_500)
}

/// The largest in cells (runs × positions), whose answer is the largest.
fn most_cells(sensor: &str) -> Vec<u8> {
    tumble(sensor, 360, 1000, 1)
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
    let sizes = (most_samples("MEM-1"), most_cells("MEM-1"));
    println!(
        "largest in samples: {} bytes of JSON ({} gzip-compressed), 2 000 000 samples; \
         largest in cells: {} bytes of JSON, 360 000 samples",
        sizes.0.len(),
        gzip(&sizes.0).len(),
        sizes.1.len()
    );
    type Body = fn(&str) -> Vec<u8>;
    let requests: [(&str, &str, Body, bool, usize); 7] = [
        (
            "identify, most samples, 1 request",
            "/v1/identify",
            most_samples,
            false,
            1,
        ),
        (
            "submit, most samples, 1 request",
            "/v1/calibrations",
            most_samples,
            false,
            1,
        ),
        (
            "submit, most samples gzip, 1 request",
            "/v1/calibrations",
            most_samples,
            true,
            1,
        ),
        (
            "submit, most samples, 2 at once",
            "/v1/calibrations",
            most_samples,
            false,
            2,
        ),
        (
            "identify, most cells, 1 request",
            "/v1/identify",
            most_cells,
            false,
            1,
        ),
        (
            "submit, most cells, 1 request",
            "/v1/calibrations",
            most_cells,
            false,
            1,
        ),
        (
            "submit, most cells, 8 at once",
            "/v1/calibrations",
            most_cells,
            false,
            8,
        ),
    ];

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
        for (label, path, body_of, gzipped, concurrent) in requests {
            let tasks = (0..concurrent).map(|n| {
                let client = client.clone();
                let url = format!("{}{path}", server.base);
                let sensor = format!("MEM-{label}-{n}").replace([' ', ',', '(', ')'], "");
                let body = body_of(&sensor);
                let body = if gzipped { gzip(&body) } else { body };
                tokio::spawn(async move {
                    let mut req = client
                        .post(url)
                        .bearer_auth(ADMIN)
                        .header("content-type", "application/json");
                    if gzipped {
                        req = req.header("content-encoding", "gzip");
                    }
                    let res = req.body(body).send().await.unwrap();
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
            .get_json("/v1/sensors/MEM-submitmostcells1request-0/calibrations")
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
