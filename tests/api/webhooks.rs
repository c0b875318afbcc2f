//! Webhooks (issue 47 item 3) as a control system receives them: endpoints
//! registered and refused, every event delivered in order, a receiver down
//! for a while getting everything with the same ids, redelivery, secret
//! rotation, giving up at the maximum age, targets refused again at
//! delivery, two replicas delivering each event once — on both engines
//! where the store is involved. The signatures are verified by the
//! `standardwebhooks` package in tests/webhooks/ (CI).

use std::collections::HashSet;
use std::time::Duration;

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal::startup::Config;
use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::receiver::{Mode, Receiver};
use accelcal_testkit::*;

/// Settings that let tests see retries in moments: loopback targets
/// allowed, 100 ms doubling to 400 ms, a second's timeout, looks every
/// 20 ms.
fn quick(c: &mut Config) {
    let w = &mut c.web.webhooks;
    w.allow_private = true;
    w.retry.base = Duration::from_millis(100);
    w.retry.cap = Duration::from_millis(400);
    w.timeout = Duration::from_secs(1);
    w.poll = Duration::from_millis(20);
}

/// Registers `id` for `body` and answers the created document.
async fn register(app: &TestApp, id: &str, body: Value) -> Value {
    let res = app.put(&format!("/v1/webhooks/{id}"), ADMIN, &body).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    res.json().await.unwrap()
}

/// Waits until the receiver accepted `n` requests.
async fn accepted(r: &Receiver, n: usize) -> Vec<accelcal_testkit::receiver::Received> {
    eventually(Duration::from_secs(20), "deliveries", || async {
        let got = r.accepted();
        (got.len() >= n).then_some(got)
    })
    .await
}

#[rstest]
#[tokio::test]
async fn registration_is_an_admins_and_is_checked(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let reviewer = app.token("reviewer", None).await;
    let body = json!({"url": "https://example.com/hook"});
    let res = app.put("/v1/webhooks/w", &reviewer, &body).await;
    problem(res, StatusCode::FORBIDDEN).await;
    let res = app.get("/v1/webhooks", &reviewer).await;
    problem(res, StatusCode::FORBIDDEN).await;
    // Private and loopback targets, by literal or by name, and malformed
    // ones: each a 422 at /url saying why.
    for (url, why) in [
        ("http://127.0.0.1:9/hook", "loopback"),
        ("http://[::1]/hook", "loopback"),
        ("http://10.0.0.7/hook", "private"),
        ("http://169.254.169.254/latest", "link-local"),
        ("http://localhost:9/hook", "loopback"),
        ("ftp://example.com/", "scheme `ftp`"),
        ("https://user:pw@example.com/", "user name or password"),
        ("hook", "is not a URL"),
    ] {
        let res = app.put("/v1/webhooks/w", ADMIN, &json!({"url": url})).await;
        let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
        assert_eq!(pointers(&p), ["/url"], "{url}: {p}");
        assert!(p.to_string().contains(why), "{url}: {p}");
    }
    let res = app
        .put(
            "/v1/webhooks/w",
            ADMIN,
            &json!({"url": "http://127.0.0.1:9/", "event_types": ["calibration.eaten"]}),
        )
        .await;
    assert!(res.status().is_client_error());
    let res = app
        .put(
            "/v1/webhooks/w",
            ADMIN,
            &json!({"url": "http://127.0.0.1:9/", "sensors": ["a b"], "extra": 1}),
        )
        .await;
    assert!(res.status().is_client_error());
    let res = app.put("/v1/webhooks/a%20b", ADMIN, &body).await;
    problem(res, StatusCode::BAD_REQUEST).await;
    for path in ["/v1/webhooks/none", "/v1/webhooks/none/deliveries"] {
        problem(app.get(path, ADMIN).await, StatusCode::NOT_FOUND).await;
    }
    let res = app
        .client
        .delete(app.url("/v1/webhooks/none"))
        .bearer_auth(ADMIN)
        .send()
        .await
        .unwrap();
    problem(res, StatusCode::NOT_FOUND).await;
    // Nothing was registered.
    let list = app.get_json("/v1/webhooks", ADMIN).await;
    assert_eq!(list["items"], json!([]));
}

/// Every event an endpoint asked for, in sequence order, once, with its
/// id `evt_{seq}`; filters by sensor and type; where its deliveries stand
/// and their log; the registration in the trail without its secret; a
/// change keeps the secret; a deleted endpoint gets nothing more.
#[rstest]
#[tokio::test]
async fn events_are_delivered_in_order(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, quick).await;
    let all = Receiver::start().await;
    let only_b = Receiver::start().await;
    let created = register(
        &app,
        "all",
        json!({"url": all.url, "description": "every event"}),
    )
    .await;
    let secret = created["secret"].as_str().unwrap();
    assert!(secret.starts_with("whsec_"), "{created}");
    assert_eq!(created["webhook"]["webhook_id"], "all");
    register(
        &app,
        "b",
        json!({"url": only_b.url, "sensors": ["WH-B"], "event_types": ["calibration.withdrawn"]}),
    )
    .await;
    let station = app.token("station", None).await;
    let mut ids = Vec::new();
    for (i, sensor) in ["WH-A", "WH-B", "WH-A"].into_iter().enumerate() {
        let c = app
            .submit(
                &station,
                &submission(sensor, &format!("2026-01-0{}T00:00:00Z", i + 1), 4),
            )
            .await;
        ids.push(c["id"].as_str().unwrap().to_owned());
    }
    let res = app
        .post(
            &format!("/v1/calibrations/{}/withdraw", ids[1]),
            ADMIN,
            &json!({"reason": "wrong fixture"}),
        )
        .await;
    assert_eq!(
        res.status(),
        StatusCode::OK,
        "{}",
        res.text().await.unwrap()
    );
    let got = accepted(&all, 4).await;
    let types: Vec<Value> = got.iter().map(|r| r.json()["type"].clone()).collect();
    assert_eq!(
        types,
        [
            "calibration.stored",
            "calibration.stored",
            "calibration.stored",
            "calibration.withdrawn"
        ]
    );
    let seqs: Vec<i64> = got.iter().map(|r| r.seq()).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    for r in &got {
        assert_eq!(r.id, format!("evt_{}", r.seq()));
        assert!(r.signature.starts_with("v1,") && !r.signature.contains(' '));
        let body = r.json();
        crate::conforms_to("WebhookPayload", &body);
        assert_eq!(body["timestamp"], body["data"]["at"]);
        assert_eq!(body["type"], body["data"]["type"]);
    }
    let calibrations: Vec<Value> = got
        .iter()
        .map(|r| r.json()["data"]["calibration_id"].clone())
        .collect();
    assert_eq!(
        calibrations,
        [json!(ids[0]), json!(ids[1]), json!(ids[2]), json!(ids[1])]
    );
    // Only B's withdrawal went to `b`.
    let b = accepted(&only_b, 1).await;
    assert_eq!(b.len(), 1);
    assert_eq!(b[0].json()["data"]["sensor_id"], "WH-B");
    assert_eq!(b[0].id, got[3].id);
    // Where they stand, and the log, newest first.
    let w = eventually(Duration::from_secs(10), "the cursor", || async {
        let w = app.get_json("/v1/webhooks/all", ADMIN).await;
        (w["delivered_through"] == json!(seqs[3])).then_some(w)
    })
    .await;
    assert_eq!(w["failed_attempts"], 0);
    assert_eq!(w["retry_at"], Value::Null);
    assert!(w.get("secret").is_none(), "{w}");
    let log = app.get_json("/v1/webhooks/all/deliveries", ADMIN).await;
    let log = log["items"].as_array().unwrap();
    assert_eq!(log.len(), 4);
    assert_eq!(log[0]["event_seq"], seqs[3]);
    assert!(
        log.iter()
            .all(|d| d["outcome"] == "delivered" && d["status"] == 204 && d["attempt"] == 1)
    );
    problem(
        app.get("/v1/webhooks/all/deliveries?limit=0", ADMIN).await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    // Recorded in the trail: the secret's digest, never the secret.
    let put = app.trail_entry("webhooks/all", "webhook.put").await;
    assert!(put["change"]["secret_sha256"].is_string(), "{put}");
    assert!(!put.to_string().contains(secret));
    // A change keeps the secret (none shown) and where deliveries stand.
    let res = app
        .put(
            "/v1/webhooks/all",
            ADMIN,
            &json!({"url": all.url, "sensors": ["WH-A"]}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let changed: Value = res.json().await.unwrap();
    assert!(changed.get("secret").is_none());
    assert_eq!(changed["delivered_through"], seqs[3]);
    assert_eq!(changed["sensors"], json!(["WH-A"]));
    let list = app.get_json("/v1/webhooks", ADMIN).await;
    let listed: Vec<&str> = list["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["webhook_id"].as_str().unwrap())
        .collect();
    assert_eq!(listed, ["all", "b"]);
    // Deleted: no more deliveries.
    let res = app
        .client
        .delete(app.url("/v1/webhooks/all"))
        .bearer_auth(ADMIN)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::NO_CONTENT);
    app.submit(&station, &submission("WH-A", "2026-01-09T00:00:00Z", 4))
        .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(all.received().len(), 4);
    problem(
        app.get("/v1/webhooks/all", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;
}

/// A receiver that fails gets its first event again and again with the
/// same id — never the next before it — each attempt logged; once it
/// answers, it gets everything, in order.
#[rstest]
#[tokio::test]
async fn a_receiver_down_gets_everything_once_up(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, quick).await;
    let r = Receiver::start().await;
    r.set(Mode::Fail(503));
    register(&app, "w", json!({"url": r.url})).await;
    for i in 0..3 {
        app.submit(
            ADMIN,
            &submission("WH-DOWN", &format!("2026-02-0{}T00:00:00Z", i + 1), 4),
        )
        .await;
    }
    let failing = eventually(Duration::from_secs(20), "three failed attempts", || async {
        let got = r.received();
        (got.len() >= 3).then_some(got)
    })
    .await;
    let first = failing[0].id.clone();
    assert!(
        failing.iter().all(|f| f.id == first && !f.accepted),
        "{failing:?}"
    );
    let w = app.get_json("/v1/webhooks/w", ADMIN).await;
    assert!(w["failed_attempts"].as_i64().unwrap() >= 1, "{w}");
    assert!(w["retry_at"].is_string(), "{w}");
    let log = app.get_json("/v1/webhooks/w/deliveries", ADMIN).await;
    let newest = &log["items"][0];
    assert_eq!(
        (newest["outcome"].as_str(), newest["status"].as_i64()),
        (Some("failed"), Some(503))
    );
    assert_eq!(newest["message_id"], json!(first));
    r.set(Mode::Accept);
    let got = accepted(&r, 3).await;
    let ids: Vec<&str> = got.iter().map(|g| g.id.as_str()).collect();
    assert_eq!(ids[0], first);
    let seqs: Vec<i64> = got.iter().map(|g| g.seq()).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    assert_eq!(ids.iter().collect::<HashSet<_>>().len(), 3);
}

/// Redelivery after an event id sends those events again, in order, with
/// their ids; rotation signs with both secrets during its overlap.
#[rstest]
#[tokio::test]
async fn redelivery_and_rotation(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::configured(engine, quick).await;
    let r = Receiver::start().await;
    register(&app, "w", json!({"url": r.url})).await;
    for i in 0..2 {
        app.submit(
            ADMIN,
            &submission("WH-RE", &format!("2026-03-0{}T00:00:00Z", i + 1), 4),
        )
        .await;
    }
    let first = accepted(&r, 2).await;
    let after = first[0].seq() - 1;
    for bad in [json!({"after": -1}), json!({"after": 1_000_000_000})] {
        let res = app.post("/v1/webhooks/w/redeliver", ADMIN, &bad).await;
        let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
        assert_eq!(pointers(&p), ["/after"]);
    }
    let res = app
        .post("/v1/webhooks/w/redeliver", ADMIN, &json!({"after": after}))
        .await;
    assert_eq!(res.status(), StatusCode::ACCEPTED);
    let again = accepted(&r, 4).await;
    let ids: Vec<&str> = again.iter().map(|g| g.id.as_str()).collect();
    assert_eq!(ids[2..], ids[..2]);
    assert_eq!(
        app.trail_actions("webhooks/w").await,
        ["webhook.put", "webhook.redeliver"]
    );
    // Rotation: a new secret, both signing during the overlap.
    let res = app
        .post(
            "/v1/webhooks/w/secret",
            ADMIN,
            &json!({"overlap_s": 9_999_999}),
        )
        .await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(pointers(&p), ["/overlap_s"]);
    let res = app
        .post("/v1/webhooks/w/secret", ADMIN, &json!({"overlap_s": 3600}))
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let rotated: Value = res.json().await.unwrap();
    assert!(rotated["secret"].as_str().unwrap().starts_with("whsec_"));
    assert!(rotated["webhook"]["previous_secret_until"].is_string());
    app.submit(ADMIN, &submission("WH-RE", "2026-03-09T00:00:00Z", 4))
        .await;
    let got = accepted(&r, 5).await;
    let two: Vec<&str> = got[4].signature.split(' ').collect();
    assert_eq!(two.len(), 2, "{}", got[4].signature);
    assert!(two.iter().all(|s| s.starts_with("v1,")));
    assert_ne!(two[0], two[1]);
}

/// An event older than the maximum age is given up after its failed
/// attempt (logged `abandoned`), and the next is tried.
#[rstest]
#[tokio::test]
async fn an_event_past_its_age_is_given_up(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::configured(engine, |c| {
        quick(c);
        c.web.webhooks.retry.max_age = Duration::from_millis(300);
    })
    .await;
    let r = Receiver::start().await;
    r.set(Mode::Fail(500));
    register(&app, "w", json!({"url": r.url})).await;
    app.submit(ADMIN, &submission("WH-OLD", "2026-04-01T00:00:00Z", 4))
        .await;
    let log = eventually(Duration::from_secs(20), "an abandoned event", || async {
        let log = app.get_json("/v1/webhooks/w/deliveries", ADMIN).await;
        (log["items"][0]["outcome"] == "abandoned").then_some(log)
    })
    .await;
    assert_eq!(log["items"][0]["status"], 500);
    r.set(Mode::Accept);
    app.submit(ADMIN, &submission("WH-OLD", "2026-04-02T00:00:00Z", 4))
        .await;
    let got = accepted(&r, 1).await;
    assert_eq!(
        got[0].json()["data"]["change"]["performed_at"],
        "2026-04-02T00:00:00.000000Z"
    );
}

/// A target registered while private addresses were allowed is refused at
/// delivery, after resolution, once they are not: the attempt fails and
/// says why; nothing is sent.
#[rstest]
#[tokio::test]
async fn private_targets_are_refused_again_at_delivery(#[values(Sqlite)] engine: Engine) {
    let mut app = TestApp::configured(engine, quick).await;
    let r = Receiver::start().await;
    let url = r.url.replace("127.0.0.1", "localhost");
    register(&app, "w", json!({"url": url})).await;
    let db = app.take_database().unwrap();
    app.stop().await;
    let mut config = Config::for_tests(&db.url, ADMIN);
    quick(&mut config);
    config.web.webhooks.allow_private = false;
    let app = TestApp::spawn_with(config).await;
    app.submit(ADMIN, &submission("WH-PRIV", "2026-05-01T00:00:00Z", 4))
        .await;
    let log = eventually(Duration::from_secs(20), "a refused attempt", || async {
        let log = app.get_json("/v1/webhooks/w/deliveries", ADMIN).await;
        (log["items"].as_array().is_some_and(|l| !l.is_empty())).then_some(log)
    })
    .await;
    let attempt = &log["items"][0];
    assert_eq!(attempt["outcome"], "failed");
    assert_eq!(attempt["status"], Value::Null);
    assert!(
        attempt["error"].as_str().unwrap().contains("loopback"),
        "{attempt}"
    );
    assert!(r.received().is_empty());
}

/// Two replicas over one database deliver each event to an endpoint once,
/// in order, whichever replica's act it was.
#[rstest]
#[tokio::test]
async fn two_replicas_deliver_each_event_once(#[values(Postgres)] engine: Engine) {
    let one = TestApp::configured(engine, quick).await;
    let mut config = Config::for_tests(&one.database, ADMIN);
    quick(&mut config);
    let two = TestApp::spawn_with(config).await;
    let r = Receiver::start().await;
    register(&one, "w", json!({"url": r.url})).await;
    let n = 20;
    for i in 0..n {
        let app = if i % 2 == 0 { &one } else { &two };
        let at = format!("2026-06-01T00:{:02}:00Z", i);
        app.submit(ADMIN, &submission(&format!("WH-R{}", i % 3), &at, 4))
            .await;
    }
    let got = accepted(&r, n).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let got_all = r.received();
    assert_eq!(
        got_all.len(),
        n,
        "each event once: {:?}",
        got_all.iter().map(|g| &g.id).collect::<Vec<_>>()
    );
    let seqs: Vec<i64> = got.iter().map(|g| g.seq()).collect();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
}

/// A sensor whose due date passed (or comes within 30 days) changes status
/// with no act: the change is announced once, within the scan interval, as
/// `sensor.status` — once even with two replicas scanning (PostgreSQL).
#[rstest]
#[tokio::test]
async fn a_status_changed_by_the_clock_is_one_event(#[values(Sqlite, Postgres)] engine: Engine) {
    let scan = |c: &mut Config| {
        quick(c);
        c.web.status_scan = Duration::from_millis(100);
    };
    let one = TestApp::configured(engine, scan).await;
    let _two = match engine {
        Postgres => {
            let mut config = Config::for_tests(&one.database, ADMIN);
            scan(&mut config);
            Some(TestApp::spawn_with(config).await)
        }
        Sqlite => None,
    };
    let r = Receiver::start().await;
    register(
        &one,
        "w",
        json!({"url": r.url, "event_types": ["sensor.status"]}),
    )
    .await;
    let res = one
        .put(
            "/v1/sensor-types/CLOCK",
            ADMIN,
            &json!({"label": "Clock", "unit": "mA", "limits": {"k0": {"min": -1, "max": 1}},
                    "decision_rule": "simple", "interval_days": 180}),
        )
        .await;
    assert!(res.status().is_success(), "{}", res.text().await.unwrap());
    let soon = accelcal::domain::timestamp::Timestamp::now().plus_seconds(-170 * 86_400);
    for (sensor, at) in [
        ("CLK-OLD", "2020-01-01T00:00:00Z".to_owned()),
        ("CLK-SOON", soon.to_string()),
    ] {
        let mut body = submission(sensor, &at, 4);
        body["sensor_type"] = json!("CLOCK");
        one.submit(ADMIN, &body).await;
    }
    let got = accepted(&r, 2).await;
    tokio::time::sleep(Duration::from_millis(600)).await; // several more scans
    let got_all = r.received();
    assert_eq!(got_all.len(), 2, "each change once: {got_all:?}");
    let mut seen: Vec<(String, String, Value)> = got
        .iter()
        .map(|g| {
            let d = g.json()["data"].clone();
            (
                d["sensor_id"].as_str().unwrap().to_owned(),
                d["change"]["to"].as_str().unwrap().to_owned(),
                d["change"]["from"].clone(),
            )
        })
        .collect();
    seen.sort_by(|a, b| a.0.cmp(&b.0));
    assert_eq!(
        seen,
        [
            ("CLK-OLD".to_owned(), "overdue".to_owned(), Value::Null),
            ("CLK-SOON".to_owned(), "due_soon".to_owned(), Value::Null),
        ]
    );
    let sensor = one.get_json("/v1/sensors/CLK-OLD", ADMIN).await;
    assert_eq!(sensor["status"], "overdue");
    assert!(got[0].json()["data"]["change"]["due_at"].is_string());
}
