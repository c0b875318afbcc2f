//! `--metrics-listen`: Prometheus metrics on their own listener, counting
//! exactly what was asked of the service.

use std::collections::HashMap;

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::process::{ADMIN, Server};

fn paper() -> Value {
    serde_json::from_str(include_str!("../../examples/paper-table1.json")).unwrap()
}

/// Every sample of the text format: `name{labels}` → value.
fn samples(text: &str) -> HashMap<String, f64> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .map(|l| {
            let (k, v) = l.rsplit_once(' ').unwrap();
            (k.to_owned(), v.parse().unwrap())
        })
        .collect()
}

#[tokio::test]
async fn metrics_count_what_was_asked() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start_with(
        dir.path().join("accelcal.db"),
        &["--metrics-listen", "127.0.0.1:0"],
        "info",
    );
    let metrics_addr = server
        .log
        .lock()
        .unwrap()
        .iter()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .find(|v| v["message"] == "metrics listening")
        .and_then(|v| v["address"].as_str().map(str::to_owned))
        .expect("the metrics listener is logged");
    let c = reqwest::Client::new();
    let post = |body: Value, key: Option<&str>| {
        let mut req = c
            .post(format!("{}/v1/calibrations", server.base))
            .bearer_auth(ADMIN)
            .json(&body);
        if let Some(k) = key {
            req = req.header("idempotency-key", k);
        }
        req.send()
    };
    let type_nav: Value =
        serde_json::from_str(include_str!("../../examples/sensor-type-nav.json")).unwrap();
    let put = c
        .put(format!("{}/v1/sensor-types/NAV", server.base))
        .bearer_auth(ADMIN)
        .json(&type_nav)
        .send()
        .await
        .unwrap();
    assert_eq!(put.status(), StatusCode::CREATED);
    let mut typed = paper();
    typed["sensor_type"] = json!("NAV");
    typed["sensor_id"] = json!("TYPED-1");
    assert_eq!(
        post(paper(), Some("k-1")).await.unwrap().status(),
        StatusCode::CREATED
    );
    assert_eq!(
        post(paper(), Some("k-1")).await.unwrap().status(),
        StatusCode::CREATED
    ); // replayed
    assert_eq!(
        post(typed, None).await.unwrap().status(),
        StatusCode::CREATED
    );
    assert_eq!(
        post(json!({"sensor_id": "X"}), None)
            .await
            .unwrap()
            .status(),
        StatusCode::UNPROCESSABLE_ENTITY
    );
    let anonymous = c
        .post(format!("{}/v1/calibrations", server.base))
        .json(&paper())
        .send()
        .await
        .unwrap();
    assert_eq!(anonymous.status(), StatusCode::UNAUTHORIZED);
    for _ in 0..3 {
        let r = c
            .get(format!("{}/v1/sensors/PAPER-2005", server.base))
            .bearer_auth(ADMIN)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), StatusCode::OK);
    }
    // One more calibration of the cached sensor: its submission's own read
    // of the sensor is the fourth hit, and the write keeps it cached.
    assert_eq!(
        post(paper(), None).await.unwrap().status(),
        StatusCode::CREATED
    );
    let nowhere = c
        .get(format!("{}/no/such/path/{}", server.base, "x".repeat(40)))
        .send()
        .await
        .unwrap();
    assert_eq!(nowhere.status(), StatusCode::NOT_FOUND);

    // The API is not on the metrics listener, the metrics are not on the API's.
    let on_api = c
        .get(format!("{}/metrics", server.base))
        .send()
        .await
        .unwrap();
    assert_eq!(on_api.status(), StatusCode::NOT_FOUND);
    let res = c
        .get(format!("http://{metrics_addr}/metrics"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::OK);
    assert!(
        res.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/plain; version=0.0.4")
    );
    let text = res.text().await.unwrap();
    let m = samples(&text);
    let get = |k: &str| {
        m.get(k)
            .copied()
            .unwrap_or_else(|| panic!("{k} missing from\n{text}"))
    };
    assert_eq!(
        get(r#"accelcal_submissions_total{outcome="stored",reason="none"}"#),
        3.0
    );
    assert_eq!(
        get(r#"accelcal_submissions_total{outcome="replayed",reason="none"}"#),
        1.0
    );
    assert_eq!(
        get(r#"accelcal_submissions_total{outcome="refused",reason="validation"}"#),
        1.0
    );
    assert_eq!(
        get(r#"accelcal_submissions_total{outcome="refused",reason="unauthorized"}"#),
        1.0
    );
    assert_eq!(get(r#"accelcal_verdicts_total{verdict="pass"}"#), 1.0);
    assert_eq!(
        get(r#"accelcal_http_requests_total{method="POST",route="/v1/calibrations",status="201"}"#),
        4.0
    );
    assert_eq!(
        get(
            r#"accelcal_http_requests_total{method="GET",route="/v1/sensors/{sensor_id}",status="200"}"#
        ),
        3.0
    );
    assert_eq!(
        get(r#"accelcal_http_requests_total{method="GET",route="unmatched",status="404"}"#),
        2.0
    );
    assert_eq!(
        get(
            r#"accelcal_http_request_duration_seconds_count{method="GET",route="/v1/sensors/{sensor_id}",status="200"}"#
        ),
        3.0
    );
    assert_eq!(get("accelcal_http_requests_in_flight"), 0.0);
    // The log is read as it is written: no line was dropped.
    assert_eq!(get("accelcal_log_lines_dropped_total"), 0.0);
    assert_eq!(
        get(concat!(
            r#"accelcal_build_info{version=""#,
            env!("CARGO_PKG_VERSION"),
            r#""}"#
        )),
        1.0
    );
    assert!(
        get(
            r#"accelcal_storage_operation_duration_seconds_count{operation="insert_calibration",outcome="ok"}"#
        ) >= 2.0
    );
    // Each write left its sensor cached with the row the database
    // answered, so the three reads after it and the next submission's read
    // are all answered from the cache; the two first submissions' reads of
    // their sensors, before any write, were not.
    assert_eq!(get(r#"accelcal_sensor_cache_total{outcome="hit"}"#), 4.0);
    assert!(get(r#"accelcal_sensor_cache_total{outcome="miss"}"#) >= 2.0);
    assert_eq!(
        get(r#"accelcal_sensor_cache_writes_total{outcome="kept"}"#),
        3.0
    );
    assert_eq!(
        m.get(r#"accelcal_sensor_cache_writes_total{outcome="dropped"}"#)
            .copied()
            .unwrap_or(0.0),
        0.0
    );
    // Group commit: at least the two stored calibrations and the key's
    // claim went through the writer, in at most as many batches.
    let batched = get("accelcal_storage_write_batch_size_sum");
    let batches = get("accelcal_storage_write_batch_size_count");
    assert!(batched >= 3.0, "{batched} writes batched");
    assert!((1.0..=batched).contains(&batches), "{batches} batches");
    assert_eq!(
        get(r#"accelcal_storage_write_batch_size_bucket{le="256"}"#),
        batches,
        "batch sizes are a histogram with size buckets, none above 256"
    );
    // Every family has help text and a type (what `promtool check metrics`
    // insists on).
    let families: std::collections::BTreeSet<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("# TYPE "))
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert!(families.len() >= 9, "{families:?}");
    for family in families {
        assert!(
            text.lines().any(|l| l
                .strip_prefix("# HELP ")
                .is_some_and(|h| h.split_whitespace().next() == Some(family))),
            "{family} has no help text"
        );
    }
    assert!(
        !text.contains("/no/such/path"),
        "raw paths never become labels"
    );
}
