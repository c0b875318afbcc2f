//! Live events (issue 47 item 2): `GET /v1/events` as a dashboard reads it
//! — every act's event in order, filters, resuming with `Last-Event-ID`,
//! two replicas' events on one stream, refusals, and a stream that does
//! not hold a shutdown — on both engines.

use std::time::Duration;

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;

/// Checks an event's `data` against the committed contract's `LiveEvent`:
/// every required property, no other, and a type the contract lists (the
/// stream itself is left out of schemathesis's run, which would wait for
/// its end: tests/contract/run.sh).
fn conforms(data: &Value) {
    crate::conforms_to("LiveEvent", data);
    let doc: Value = serde_norway::from_str(include_str!("../../openapi.yaml")).unwrap();
    let types = doc["components"]["schemas"]["EventType"]["enum"]
        .as_array()
        .unwrap();
    assert!(types.contains(&data["type"]), "{data}");
}

/// One event as read off the wire.
#[derive(Debug)]
struct Sent {
    id: i64,
    event: String,
    data: Value,
}

/// An open event stream, parsed frame by frame (blank-line separated;
/// comment frames skipped).
struct Stream {
    res: reqwest::Response,
    buf: String,
}

impl Stream {
    async fn open(app: &TestApp, token: &str, query: &str, last: Option<i64>) -> Stream {
        let mut req = app
            .client
            .get(app.url(&format!("/v1/events{query}")))
            .bearer_auth(token);
        if let Some(id) = last {
            req = req.header("Last-Event-ID", id.to_string());
        }
        let res = req.send().await.unwrap();
        assert_eq!(res.status(), StatusCode::OK);
        assert_eq!(
            res.headers()["content-type"].to_str().unwrap(),
            "text/event-stream"
        );
        Stream {
            res,
            buf: String::new(),
        }
    }

    /// The next event, within `wait`; `None` when none came (or the stream
    /// ended).
    async fn within(&mut self, wait: Duration) -> Option<Sent> {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            if let Some(end) = self.buf.find("\n\n") {
                let frame: String = self.buf.drain(..end + 2).collect();
                let field = |name: &str| {
                    frame
                        .lines()
                        .find_map(|l| l.strip_prefix(name))
                        .map(str::to_owned)
                };
                let Some(data) = field("data: ") else {
                    continue; // a heartbeat
                };
                return Some(Sent {
                    id: field("id: ").unwrap().parse().unwrap(),
                    event: field("event: ").unwrap(),
                    data: serde_json::from_str(&data).unwrap(),
                });
            }
            let chunk = tokio::time::timeout_at(deadline, self.res.chunk())
                .await
                .ok()?
                .unwrap()?;
            self.buf.push_str(std::str::from_utf8(&chunk).unwrap());
        }
    }

    /// The next event, which must come within 10 s.
    async fn next(&mut self) -> Sent {
        self.within(Duration::from_secs(10))
            .await
            .expect("an event within 10 s")
    }
}

fn review(id: &Value) -> String {
    format!("/v1/calibrations/{}/review", id.as_str().unwrap())
}

#[rstest]
#[tokio::test]
async fn every_act_is_an_event_in_order_and_a_client_resumes(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let station = app.held_token("station", "Sam Station", None).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let reader = app.token("reader", None).await;
    let mut all = Stream::open(&app, &reader, "", None).await;
    let mut of_b = Stream::open(&app, &reader, "?sensor_id=EV-B,EV-C", None).await;
    let mut approvals = Stream::open(&app, &reader, "?type=calibration.approved", None).await;

    let a = app
        .submit(&station, &submission("EV-A", "2026-01-01T00:00:00Z", 4))
        .await;
    let b = app
        .submit(&station, &submission("EV-B", "2026-01-02T00:00:00Z", 4))
        .await;
    let res = app
        .post(&review(&a["id"]), &rita, &json!({"decision": "approve"}))
        .await;
    assert_eq!(
        res.status(),
        StatusCode::OK,
        "{}",
        res.text().await.unwrap()
    );

    // Every act, in the order they were made, with ids that grow.
    let got = [all.next().await, all.next().await, all.next().await];
    let seen: Vec<(&str, &str, &str)> = got
        .iter()
        .map(|e| {
            (
                e.event.as_str(),
                e.data["sensor_id"].as_str().unwrap(),
                e.data["calibration_id"].as_str().unwrap(),
            )
        })
        .collect();
    let (a_id, b_id) = (a["id"].as_str().unwrap(), b["id"].as_str().unwrap());
    assert_eq!(
        seen,
        [
            ("calibration.stored", "EV-A", a_id),
            ("calibration.stored", "EV-B", b_id),
            ("calibration.approved", "EV-A", a_id),
        ]
    );
    assert!(got[0].id < got[1].id && got[1].id < got[2].id, "{got:?}");
    for e in &got {
        conforms(&e.data);
        assert_eq!(e.data["seq"], e.id);
        assert_eq!(e.data["type"], e.event.as_str());
    }
    assert_eq!(got[2].data["change"]["to"], "approved");
    // The ids are the audit trail's: the approval's entry is there.
    let entry = app
        .trail_entry(&format!("calibrations/{a_id}"), "calibration.approve")
        .await;
    assert_eq!(entry["seq"], got[2].id);

    // The filtered streams see only theirs.
    let only_b = of_b.next().await;
    assert_eq!(
        (only_b.id, only_b.data["sensor_id"].as_str()),
        (got[1].id, Some("EV-B"))
    );
    assert_eq!(approvals.next().await.id, got[2].id);
    assert!(of_b.within(Duration::from_millis(600)).await.is_none());

    // Resuming after the first event gives the two after it, from the trail.
    let mut resumed = Stream::open(&app, &reader, "", Some(got[0].id)).await;
    assert_eq!(resumed.next().await.id, got[1].id);
    assert_eq!(resumed.next().await.id, got[2].id);
    // … and then what happens next, once.
    let c = app
        .submit(&station, &submission("EV-C", "2026-01-03T00:00:00Z", 4))
        .await;
    let next = resumed.next().await;
    assert_eq!(next.data["calibration_id"], c["id"]);
    assert!(next.id > got[2].id);
    assert_eq!(all.next().await.id, next.id);
    assert_eq!(of_b.next().await.id, next.id);
    // `after` does what `Last-Event-ID` does, with a filter.
    let mut stored_after = Stream::open(
        &app,
        &reader,
        &format!("?after={}&type=calibration.stored", got[1].id),
        None,
    )
    .await;
    assert_eq!(stored_after.next().await.id, next.id);
}

#[rstest]
#[tokio::test]
async fn bad_requests_are_refused_by_name(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let reader = app.token("reader", None).await;
    let get = |query: &'static str, last: Option<&'static str>| {
        let mut req = app
            .client
            .get(app.url(&format!("/v1/events{query}")))
            .bearer_auth(&reader);
        if let Some(l) = last {
            req = req.header("Last-Event-ID", l);
        }
        req.send()
    };
    for (query, last, named) in [
        ("?type=calibration.deleted", None, "type"),
        ("?type=", None, "type"),
        ("?sensor_id=A,,B", None, "sensor_id"),
        ("?after=-1", None, "after"),
        ("", Some("abc"), "Last-Event-ID"),
        ("", Some("999999"), "Last-Event-ID"),
        ("?colour=red", None, "colour"),
    ] {
        let p = problem(get(query, last).await.unwrap(), StatusCode::BAD_REQUEST).await;
        assert!(p.to_string().contains(named), "{query} {last:?}: {p}");
    }
    let res = app.client.get(app.url("/v1/events")).send().await.unwrap();
    assert_eq!(res.status(), StatusCode::UNAUTHORIZED);
}

/// A client of one replica sees the other replica's events, in order.
#[rstest]
#[tokio::test]
async fn two_replicas_clients_see_both_replicas_events(#[values(Postgres)] engine: Engine) {
    let one = TestApp::spawn(engine).await;
    let two = TestApp::spawn_on(&one.database).await;
    let reader = one.token("reader", None).await;
    let station = one.token("station", None).await;
    let mut on_one = Stream::open(&one, &reader, "", None).await;
    let mut on_two = Stream::open(&two, &reader, "", None).await;
    let x = two
        .submit(&station, &submission("EV-X", "2026-01-01T00:00:00Z", 4))
        .await;
    let y = one
        .submit(&station, &submission("EV-Y", "2026-01-02T00:00:00Z", 4))
        .await;
    for stream in [&mut on_one, &mut on_two] {
        let first = stream.next().await;
        let second = stream.next().await;
        assert_eq!(
            (
                first.data["calibration_id"].clone(),
                second.data["calibration_id"].clone()
            ),
            (x["id"].clone(), y["id"].clone())
        );
        assert!(first.id < second.id);
    }
}

/// An open stream does not hold the server's shutdown: it ends.
#[rstest]
#[tokio::test]
async fn a_stream_ends_at_shutdown(#[values(Sqlite)] engine: Engine) {
    let mut app = TestApp::spawn(engine).await;
    let reader = app.token("reader", None).await;
    let mut stream = Stream::open(&app, &reader, "", None).await;
    tokio::time::timeout(Duration::from_secs(10), app.stop())
        .await
        .expect("the server stopped with a stream open");
    assert!(stream.within(Duration::from_secs(5)).await.is_none());
}

/// While nothing happens, a heartbeat comment comes every
/// `--events-heartbeat`.
#[rstest]
#[tokio::test]
async fn a_quiet_stream_has_a_heartbeat(#[values(Sqlite)] engine: Engine) {
    let app = TestApp::configured(engine, |c| {
        c.web.events_heartbeat = Duration::from_millis(300);
    })
    .await;
    let reader = app.token("reader", None).await;
    let mut stream = Stream::open(&app, &reader, "", None).await;
    let mut beats = 0;
    while beats < 2 {
        let chunk = tokio::time::timeout(Duration::from_secs(5), stream.res.chunk())
            .await
            .expect("a heartbeat within 5 s")
            .unwrap()
            .unwrap();
        let text = std::str::from_utf8(&chunk).unwrap();
        assert!(text.starts_with(':'), "{text:?}");
        beats += 1;
    }
}

/// A replica's own acts go out as soon as they are in the chain, not at
/// the next look: with looks a minute apart, the event still comes at once.
#[rstest]
#[tokio::test]
async fn a_replicas_own_acts_go_out_at_once(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, |c| {
        c.web.events_poll = Duration::from_secs(60);
    })
    .await;
    let reader = app.token("reader", None).await;
    let mut stream = Stream::open(&app, &reader, "", None).await;
    for (i, sensor) in ["EV-N1", "EV-N2"].into_iter().enumerate() {
        let c = app
            .submit(
                ADMIN,
                &submission(sensor, &format!("2026-01-0{}T00:00:00Z", i + 1), 4),
            )
            .await;
        let e = stream
            .within(Duration::from_secs(5))
            .await
            .expect("the event within 5 s, long before the next look");
        assert_eq!(e.data["calibration_id"], c["id"]);
    }
}

/// A stream outlives neither its token: revoking the token ends its
/// streams within a heartbeat, and leaves another token's open.
#[rstest]
#[tokio::test]
async fn a_revoked_tokens_stream_ends(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, |c| {
        c.web.events_heartbeat = Duration::from_millis(200);
    })
    .await;
    let res = app
        .post("/v1/tokens", ADMIN, &json!({"role": "reader"}))
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let doomed: Value = res.json().await.unwrap();
    let kept = app.token("reader", None).await;
    let mut ending = Stream::open(&app, doomed["token"].as_str().unwrap(), "", None).await;
    let mut staying = Stream::open(&app, &kept, "", None).await;
    app.revoke(doomed["id"].as_str().unwrap()).await;
    let ended = tokio::time::timeout(Duration::from_secs(10), async {
        while ending.res.chunk().await.unwrap().is_some() {}
    })
    .await;
    assert!(ended.is_ok(), "the revoked token's stream ended");
    let c = app
        .submit(ADMIN, &submission("EV-KEPT", "2026-01-01T00:00:00Z", 4))
        .await;
    assert_eq!(staying.next().await.data["calibration_id"], c["id"]);
}

/// What `GET /v1/sensors/{id}/coefficients` serves now: the calibration and
/// whether its coefficients are usable (`None`: 404, nothing served).
async fn served(app: &TestApp, token: &str, sensor: &str) -> Option<(String, bool)> {
    let res = app
        .client
        .get(app.url(&format!("/v1/sensors/{sensor}/coefficients")))
        .bearer_auth(token)
        .send()
        .await
        .unwrap();
    if res.status() == StatusCode::NOT_FOUND {
        return None;
    }
    assert_eq!(res.status(), StatusCode::OK);
    let body: Value = res.json().await.unwrap();
    Some((
        body["calibration_id"].as_str().unwrap().to_owned(),
        body["usable"].as_bool().unwrap(),
    ))
}

/// Makes acts on one sensor and checks each act's event against what the
/// coefficients read served before and after it — read independently over
/// HTTP, not from the event: `changed` exactly when the served calibration
/// or its usability changed, and then the calibration served now.
struct Watch<'a> {
    app: &'a TestApp,
    reader: String,
    sensor: &'static str,
    stream: Stream,
    before: Option<(String, bool)>,
}

/// POSTs `body` to `path` as `token`: the act must be done (200).
async fn done(app: &TestApp, token: &str, path: String, body: Value) {
    let res = app.post(&path, token, &body).await;
    assert_eq!(
        res.status(),
        StatusCode::OK,
        "{}",
        res.text().await.unwrap()
    );
}

impl<'a> Watch<'a> {
    /// Watches `sensor`'s events, as a reader, from now on.
    async fn on(app: &'a TestApp, sensor: &'static str) -> Watch<'a> {
        let reader = app.token("reader", None).await;
        let stream = Stream::open(app, &reader, &format!("?sensor_id={sensor}"), None).await;
        Watch {
            app,
            reader,
            sensor,
            stream,
            before: None,
        }
    }

    /// The next event of `kind`.
    async fn next_of(&mut self, kind: &str) -> Sent {
        loop {
            let e = self.stream.next().await;
            if e.event == kind {
                conforms(&e.data);
                return e;
            }
        }
    }

    /// After an act: its event (of `kind`, skipping others such as the
    /// nonconformity's own) says what the coefficients did.
    async fn saw(&mut self, kind: &str) -> Value {
        let e = self.next_of(kind).await;
        let after = served(self.app, &self.reader, self.sensor).await;
        let expected = if after == self.before {
            json!({"changed": false})
        } else {
            json!({"changed": true, "calibration_id": after.as_ref().map(|(id, _)| id)})
        };
        assert_eq!(
            e.data["coefficients"], expected,
            "{kind}: served {:?} → {after:?}",
            self.before
        );
        assert!(e.data["change"].get("coefficients").is_none());
        self.before = after;
        e.data["coefficients"].clone()
    }
}

#[rstest]
#[tokio::test]
async fn each_event_says_what_the_served_coefficients_did(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let mut app = TestApp::spawn(engine).await;
    let stand: Value =
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap();
    let res = app.put("/v1/standards/STAND-1", ADMIN, &stand).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let station = app.held_token("station", "Sam Station", Some("ST-1")).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let mut w = Watch::on(&app, "EV-S").await;
    let submit = |at: &'static str, named: bool| {
        let mut s = submission("EV-S", at, 4);
        s["station_id"] = json!("ST-1");
        if named {
            s["standards"] = json!({"stand": "STAND-1"});
        }
        let (app, station) = (&app, station.clone());
        async move { app.submit(&station, &s).await["id"].clone() }
    };
    let post = |path: String, body: Value| done(&app, &rita, path, body);
    let withdraw = |id: &Value| format!("/v1/calibrations/{}/withdraw", id.as_str().unwrap());

    // The first calibration is served; an older one stored late is not.
    let a1 = submit("2026-03-01T00:00:00Z", false).await;
    assert_eq!(w.saw("calibration.stored").await["calibration_id"], a1);
    let a0 = submit("2026-02-01T00:00:00Z", false).await;
    assert_eq!(w.saw("calibration.stored").await["changed"], false);
    // An approval changes nothing served (every calibration counts).
    post(review(&a1), json!({"decision": "approve"})).await;
    assert_eq!(w.saw("calibration.approved").await["changed"], false);
    // Withdrawn: the older one is served again.
    post(withdraw(&a1), json!({"reason": "wrong sensor"})).await;
    assert_eq!(w.saw("calibration.withdrawn").await["calibration_id"], a0);
    // A newer one made with a standard, then found nonconforming: the same
    // calibration served, now unusable; approved again, usable again.
    let a2 = submit("2026-04-01T00:00:00Z", true).await;
    assert_eq!(w.saw("calibration.stored").await["calibration_id"], a2);
    let nc = json!({"found_at": "2026-04-15T00:00:00Z",
        "last_known_good_at": "2026-03-15T00:00:00Z",
        "reason": "Indexing error of 9″ at the 90° stop."});
    let res = app
        .post("/v1/standards/STAND-1/nonconformity", ADMIN, &nc)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    assert_eq!(w.saw("calibration.held").await["calibration_id"], a2);
    assert_eq!(w.before, Some((a2.as_str().unwrap().to_owned(), false)));
    let release = json!({"decision": "approve", "comment": "no effect: the 90° stop unused"});
    post(review(&a2), release).await;
    assert_eq!(w.saw("calibration.released").await["calibration_id"], a2);
    // A newer one stored held at once (in the nonconformity's window): one
    // transaction of two entries, each saying what its step did — served,
    // then held — while a read sees only the end of both.
    let a3 = submit("2026-04-10T00:00:00Z", true).await;
    let a3_served = json!({"changed": true, "calibration_id": a3});
    let stored = w.next_of("calibration.stored").await;
    assert_eq!(stored.data["coefficients"], a3_served);
    let held = w.next_of("calibration.held").await;
    assert_eq!(held.data["coefficients"], a3_served);
    w.before = served(&app, &w.reader, "EV-S").await;
    assert_eq!(w.before, Some((a3.as_str().unwrap().to_owned(), false)));
    // Withdrawn one after the other: at the end nothing is served.
    post(withdraw(&a3), json!({"reason": "held"})).await;
    assert_eq!(w.saw("calibration.withdrawn").await["calibration_id"], a2);
    post(withdraw(&a2), json!({"reason": "redo"})).await;
    assert_eq!(w.saw("calibration.withdrawn").await["calibration_id"], a0);
    // Corrected by its station: the correction is served as it is stored,
    // and the supersession changes nothing more.
    let mut right = submission("EV-S", "2026-02-01T00:00:00Z", 5);
    right["station_id"] = json!("ST-1");
    let path = format!(
        "/v1/calibrations/{}/supersede?reason=wrong%20runs",
        a0.as_str().unwrap()
    );
    let res = app.post(&path, &station, &right).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let r = res.json::<Value>().await.unwrap()["id"].clone();
    assert_eq!(w.saw("calibration.stored").await["calibration_id"], r);
    assert_eq!(w.saw("calibration.superseded").await["changed"], false);
    post(withdraw(&r), json!({"reason": "redo"})).await;
    let last = w.saw("calibration.withdrawn").await;
    assert_eq!(last, json!({"changed": true, "calibration_id": null}));

    // And the trail vouches for every row these acts wrote — the hold
    // placed as a calibration was stored included (PostgreSQL recorded it
    // without its nonconformities before e5e145d, and verify called the
    // untouched nonconformity edited).
    drop(w);
    app.stop().await;
    crate::audit::verifies(app.database.clone()).await;
}

#[rstest]
#[tokio::test]
async fn with_require_approval_only_approvals_change_what_is_served(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::configured(engine, |c| {
        c.web.basis = accelcal::domain::review::Basis::ApprovedOnly;
    })
    .await;
    let station = app.held_token("station", "Sam Station", None).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let mut w = Watch::on(&app, "EV-S").await;
    let submit = |at: &'static str| {
        let s = submission("EV-S", at, 4);
        let (app, station) = (&app, station.clone());
        async move { app.submit(&station, &s).await["id"].clone() }
    };
    let post = |path: String, body: Value| done(&app, &rita, path, body);
    let b1 = submit("2026-03-01T00:00:00Z").await;
    assert_eq!(w.saw("calibration.stored").await["changed"], false);
    post(review(&b1), json!({"decision": "approve"})).await;
    assert_eq!(w.saw("calibration.approved").await["calibration_id"], b1);
    let b2 = submit("2026-04-01T00:00:00Z").await;
    assert_eq!(w.saw("calibration.stored").await["changed"], false);
    post(review(&b2), json!({"decision": "approve"})).await;
    assert_eq!(w.saw("calibration.approved").await["calibration_id"], b2);
    // An older one approved late changes nothing served.
    let b0 = submit("2026-02-01T00:00:00Z").await;
    assert_eq!(w.saw("calibration.stored").await["changed"], false);
    post(review(&b0), json!({"decision": "approve"})).await;
    assert_eq!(w.saw("calibration.approved").await["changed"], false);
    let path = format!("/v1/calibrations/{}/withdraw", b2.as_str().unwrap());
    post(path, json!({"reason": "wrong sensor"})).await;
    assert_eq!(w.saw("calibration.withdrawn").await["calibration_id"], b1);
}
