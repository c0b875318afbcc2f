//! The pages' own event stream (`GET /ui/events`, issue 47 item 5), over
//! real HTTP: it needs a session (204 without one, which stops a browser's
//! reconnecting), carries one sensor's events unnamed (the pages' script
//! listens to `message`), ends with the session, and the pages that follow
//! it name it and their script (tests/ui/ checks the refresh in a real
//! browser).

use std::time::Duration;

use reqwest::StatusCode;
use reqwest::header::{CONTENT_TYPE, LOCATION};
use rstest::rstest;
use serde_json::Value;

use crate::ui::{page, sign_in};
use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::{ADMIN, TestApp, paper, submission};

/// The frames of `res` until one carries data: its lines.
async fn next_event(res: &mut reqwest::Response, buf: &mut String) -> Vec<String> {
    loop {
        if let Some(end) = buf.find("\n\n") {
            let frame: String = buf.drain(..end + 2).collect();
            let lines: Vec<String> = frame.lines().map(str::to_owned).collect();
            if lines.iter().any(|l| l.starts_with("data:")) {
                return lines;
            }
            continue;
        }
        let chunk = tokio::time::timeout(Duration::from_secs(10), res.chunk())
            .await
            .expect("an event within 10 s")
            .unwrap()
            .expect("the stream stays open");
        buf.push_str(std::str::from_utf8(&chunk).unwrap());
    }
}

#[rstest]
#[tokio::test]
async fn the_pages_follow_their_sensors_events(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::configured(engine, |c| {
        c.web.events_heartbeat = Duration::from_millis(200);
    })
    .await;
    let anonymous = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    let res = anonymous
        .get(app.url("/ui/events?sensor_id=LIVE-A"))
        .send()
        .await
        .unwrap();
    // Without a session: 204, which stops a browser's EventSource (the
    // sign-in form's redirect would be HTML it refuses noisily).
    assert_eq!(res.status(), StatusCode::NO_CONTENT, "a session first");
    assert!(res.headers().get(LOCATION).is_none());
    assert_eq!(res.headers()["cache-control"], "no-store");

    let reader = app.token("reader", None).await;
    app.submit(ADMIN, &paper()).await;
    let (session, _) = sign_in(&app, &reader).await;
    let refused = page(&app, "/ui/events?sensor=LIVE-A", &session).await;
    assert_eq!(
        refused.status(),
        StatusCode::BAD_REQUEST,
        "an unknown parameter"
    );

    let mut stream = page(&app, "/ui/events?sensor_id=LIVE-A", &session).await;
    assert_eq!(stream.status(), StatusCode::OK);
    assert_eq!(stream.headers()[CONTENT_TYPE], "text/event-stream");
    app.submit(ADMIN, &submission("LIVE-B", "2026-01-01T00:00:00Z", 4))
        .await;
    let a = app
        .submit(ADMIN, &submission("LIVE-A", "2026-01-02T00:00:00Z", 4))
        .await;
    let mut buf = String::new();
    let lines = next_event(&mut stream, &mut buf).await;
    assert!(
        !lines.iter().any(|l| l.starts_with("event:")),
        "unnamed, so one `message` listener sees every type: {lines:?}"
    );
    assert!(lines.iter().any(|l| l.starts_with("id: ")), "{lines:?}");
    let data: Value =
        serde_json::from_str(lines.iter().find_map(|l| l.strip_prefix("data: ")).unwrap()).unwrap();
    assert_eq!(data["type"], "calibration.stored");
    assert_eq!(
        data["sensor_id"], "LIVE-A",
        "LIVE-B's event, stored first, is not this page's"
    );
    assert_eq!(data["calibration_id"], a["id"]);

    // The fleet and the sensor page name the stream and the script; the
    // script is served, cached for good under its hash; the
    // Content-Security-Policy allows this origin's script and nothing inline.
    for (path, stream) in [
        ("/ui/sensors", r#"data-live="/ui/events""#),
        (
            "/ui/sensors/LIVE-A",
            r#"data-live="/ui/events?sensor_id=LIVE-A""#,
        ),
    ] {
        let res = page(&app, path, &session).await;
        let csp = res.headers()["content-security-policy"]
            .to_str()
            .unwrap()
            .to_owned();
        assert!(
            csp.contains("script-src 'self'") && csp.contains("connect-src 'self'"),
            "{csp}"
        );
        let html = res.text().await.unwrap();
        assert!(html.contains(stream), "{path}");
        assert!(html.contains(r#"id="live-status""#), "{path}");
        let at = html.find("<script src=\"").expect("the script") + 13;
        let src = &html[at..at + html[at..].find('"').unwrap()];
        assert!(
            src.starts_with("/ui/assets/live-") && src.ends_with(".js"),
            "{src}"
        );
        assert_eq!(
            html.matches("<script").count(),
            1,
            "one script, none inline"
        );
        let js = anonymous.get(app.url(src)).send().await.unwrap();
        assert_eq!(js.status(), StatusCode::OK);
        assert_eq!(js.headers()[CONTENT_TYPE], "text/javascript; charset=utf-8");
        assert_eq!(
            js.headers()["cache-control"],
            "public, max-age=31536000, immutable"
        );
        assert!(js.text().await.unwrap().contains("new EventSource"));
    }
    // Signing out ends the page's stream (looked at every heartbeat).
    let form = page(&app, "/ui/sensors", &session)
        .await
        .text()
        .await
        .unwrap();
    let at = form.find(r#"name="csrf" value=""#).unwrap() + 19;
    let csrf = &form[at..at + form[at..].find('"').unwrap()];
    let mut ending = page(&app, "/ui/events", &session).await;
    assert_eq!(ending.status(), StatusCode::OK);
    let out = anonymous
        .post(app.url("/ui/logout"))
        .header("cookie", format!("accelcal_session={session}"))
        .form(&[("csrf", csrf)])
        .send()
        .await
        .unwrap();
    assert_eq!(out.status(), StatusCode::SEE_OTHER);
    let ended = tokio::time::timeout(Duration::from_secs(10), async {
        while ending.chunk().await.unwrap().is_some() {}
    })
    .await;
    assert!(ended.is_ok(), "the signed-out session's stream ended");
    let reconnect = page(&app, "/ui/events", &session).await;
    assert_eq!(
        reconnect.status(),
        StatusCode::NO_CONTENT,
        "the browser's reconnection is told to stop"
    );
    // A revoked token's stream is refused alike, and leaves the session for
    // the page, which says why it ended.
    let doomed: Value = app
        .post("/v1/tokens", ADMIN, &serde_json::json!({"role": "reader"}))
        .await
        .json()
        .await
        .unwrap();
    let (gone, _) = sign_in(&app, doomed["token"].as_str().unwrap()).await;
    app.revoke(doomed["id"].as_str().unwrap()).await;
    for _ in 0..2 {
        let refused = page(&app, "/ui/events?sensor=LIVE-A", &gone).await;
        assert_eq!(
            refused.status(),
            StatusCode::NO_CONTENT,
            "the session first"
        );
    }
    let res = page(&app, "/ui/sensors", &gone).await;
    assert_eq!(res.status(), StatusCode::SEE_OTHER);
    assert!(
        res.headers()[LOCATION]
            .to_str()
            .unwrap()
            .ends_with("&reason=ended")
    );
    let (session, _) = sign_in(&app, &reader).await;

    // A calibration's page changes only by a reviewer's act on it: no script.
    let html = page(
        &app,
        &format!("/ui/calibrations/{}", a["id"].as_str().unwrap()),
        &session,
    )
    .await
    .text()
    .await
    .unwrap();
    assert!(!html.contains("<script"));
}
