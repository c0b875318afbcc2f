//! No lost updates (issue 42 item 6): writes of a definition read and write
//! in one transaction, so concurrent recalibrations of a standard keep every
//! certificate; and a client that writes what it read sends its `ETag` in
//! `If-Match`, and a stale write is refused (412) instead of replacing what
//! someone else wrote since.

use futures_util::future::join_all;
use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

fn stand() -> Value {
    serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap()
}

/// The stand recalibrated by certificate `CAL-{n}` on day `n` of 2026.
fn recalibrated(n: usize) -> Value {
    let mut s = stand();
    s["certificate"]["number"] = json!(format!("CAL-{n}"));
    s["certificate"]["calibrated_at"] = json!(format!("2026-02-{:02}T00:00:00Z", n + 1));
    s["due_at"] = json!("2027-03-01T00:00:00Z");
    s
}

async fn put_with(
    app: &TestApp,
    path: &str,
    body: &Value,
    headers: &[(&str, &str)],
) -> reqwest::Response {
    let mut req = app.client.put(app.url(path)).bearer_auth(ADMIN).json(body);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    req.send().await.unwrap()
}

/// Ten times, four recalibrations of one stand sent at once: every one is
/// answered 2xx, and every certificate is in the standard's history — the
/// one in force and the earlier ones.
#[rstest]
#[tokio::test]
async fn concurrent_recalibrations_keep_every_certificate(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    for trial in 0..10 {
        let path = format!("/v1/standards/DH-{trial}");
        assert_eq!(
            app.put(&path, ADMIN, &stand()).await.status(),
            StatusCode::CREATED
        );
        let bodies: Vec<Value> = (1..=4).map(recalibrated).collect();
        let answers = join_all(bodies.iter().map(|b| app.put(&path, ADMIN, b))).await;
        for a in answers {
            assert_eq!(a.status(), StatusCode::OK, "trial {trial}");
        }
        let s = app.get_json(&path, ADMIN).await;
        let mut numbers: Vec<String> = std::iter::once(&s["certificate"])
            .chain(
                s["earlier"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| &p["certificate"]),
            )
            .map(|c| c["number"].as_str().unwrap().to_owned())
            .collect();
        numbers.sort();
        assert_eq!(
            numbers,
            ["CAL-1", "CAL-2", "CAL-2026-0117", "CAL-3", "CAL-4"],
            "trial {trial}: {s}"
        );
        // Every write is in the trail.
        let trail = app
            .get_json(&format!("/v1/audit?object=standards/DH-{trial}"), ADMIN)
            .await;
        assert_eq!(trail["items"].as_array().unwrap().len(), 5, "trial {trial}");
    }
}

/// A write sent with the `ETag` it read replaces the record only if nobody
/// wrote it since: of writes sent at once with the same `ETag`, exactly one
/// is applied and the others are 412 with the current `ETag`; `If-None-Match:
/// *` creates only; `If-Match: *` replaces only. Standards, customers, items
/// and sensor types alike.
#[rstest]
#[tokio::test]
async fn a_stale_write_is_refused_not_applied(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let customer =
        |name: &str| json!({"name": name, "address": "1 Gyro Way", "due_date_agreed": true});
    let sensor_type = |days: u32| {
        json!({"unit": "output", "limits": {"k0": {"max": 0.01}}, "decision_rule": "simple",
               "interval_days": days})
    };
    let item =
        |serial: &str| json!({"manufacturer": "Honeywell", "model": "QA-3000", "serial": serial});
    let cases: Vec<(String, Value, Vec<Value>)> = vec![
        (
            "/v1/standards/DH-E".into(),
            stand(),
            (1..=4).map(recalibrated).collect(),
        ),
        (
            "/v1/customers/ACME".into(),
            customer("Acme"),
            (1..=4).map(|n| customer(&format!("Acme {n}"))).collect(),
        ),
        (
            "/v1/sensor-types/NAV".into(),
            sensor_type(365),
            (1..=4).map(|n| sensor_type(100 + n)).collect(),
        ),
        (
            "/v1/sensors/QA-1/item".into(),
            item("QA-0"),
            (1..=4).map(|n| item(&format!("QA-{n}"))).collect(),
        ),
    ];
    for (path, first, edits) in cases {
        // Create only: once.
        let created = put_with(&app, &path, &first, &[("If-None-Match", "*")]).await;
        assert_eq!(created.status(), StatusCode::CREATED, "{path}");
        let etag = created.headers()["etag"].to_str().unwrap().to_owned();
        let again = put_with(&app, &path, &first, &[("If-None-Match", "*")]).await;
        assert_eq!(again.status(), StatusCode::PRECONDITION_FAILED, "{path}");
        assert_eq!(again.headers()["etag"], etag.as_str());
        let p = problem(again, StatusCode::PRECONDITION_FAILED).await;
        assert_eq!(p["type"], "urn:accelcal:problem:precondition-failed");
        // GET answers the same tag.
        let got = app.get(&path, ADMIN).await;
        assert_eq!(got.headers()["etag"], etag.as_str(), "{path}");
        // Four edits of what was read, sent at once: one applies.
        let if_match = [("If-Match", etag.as_str())];
        let answers = join_all(edits.iter().map(|e| put_with(&app, &path, e, &if_match))).await;
        let statuses: Vec<StatusCode> = answers.iter().map(|a| a.status()).collect();
        assert_eq!(
            statuses.iter().filter(|s| **s == StatusCode::OK).count(),
            1,
            "{path}: {statuses:?}"
        );
        assert_eq!(
            statuses
                .iter()
                .filter(|s| **s == StatusCode::PRECONDITION_FAILED)
                .count(),
            3,
            "{path}: {statuses:?}"
        );
        let now = app.get(&path, ADMIN).await.headers()["etag"].clone();
        assert_ne!(now, etag.as_str(), "{path}");
        // The stale tag stays stale; the current one works; * needs a record.
        let stale = put_with(&app, &path, &edits[0], &[("If-Match", &etag)]).await;
        assert_eq!(stale.status(), StatusCode::PRECONDITION_FAILED, "{path}");
        let fresh = put_with(
            &app,
            &path,
            &edits[0],
            &[("If-Match", now.to_str().unwrap())],
        )
        .await;
        assert_eq!(fresh.status(), StatusCode::OK, "{path}");
        let star = put_with(&app, &path, &edits[1], &[("If-Match", "*")]).await;
        assert_eq!(star.status(), StatusCode::OK, "{path}");
    }
    let nothing = put_with(
        &app,
        "/v1/customers/NOBODY",
        &customer("x"),
        &[("If-Match", "*")],
    )
    .await;
    assert_eq!(nothing.status(), StatusCode::PRECONDITION_FAILED);
    assert_eq!(
        app.get("/v1/customers/NOBODY", ADMIN).await.status(),
        StatusCode::NOT_FOUND
    );
    // A malformed precondition is the header's fault.
    let bad = put_with(
        &app,
        "/v1/customers/ACME",
        &customer("y"),
        &[("If-Match", "abc")],
    )
    .await;
    let p = problem(bad, StatusCode::BAD_REQUEST).await;
    assert!(p["detail"].as_str().unwrap().contains("If-Match"), "{p}");
}
