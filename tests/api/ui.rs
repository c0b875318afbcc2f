//! The web pages over real HTTP, without a browser (tests/ui/ drives a real
//! one): sign-in, sessions, CSRF, redirects, headers, and the certificate
//! checked against independent computations.

use std::time::Duration;

use accelcal::startup::Web;
use reqwest::header::{CONTENT_TYPE, LOCATION, SET_COOKIE};
use reqwest::redirect::Policy;
use reqwest::{Client, StatusCode};
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::{ADMIN, TestApp, misfit_submission, paper};
use rstest::rstest;

fn browser() -> Client {
    Client::builder().redirect(Policy::none()).build().unwrap()
}

/// The value of `name` in a response's `Set-Cookie` headers, and the whole header.
fn set_cookie(res: &reqwest::Response, name: &str) -> Option<(String, String)> {
    res.headers().get_all(SET_COOKIE).iter().find_map(|v| {
        let text = v.to_str().ok()?.to_owned();
        let value = text
            .strip_prefix(&format!("{name}="))?
            .split(';')
            .next()?
            .to_owned();
        Some((value, text))
    })
}

fn hidden(html: &str, name: &str) -> String {
    let at = html.find(&format!(r#"name="{name}" value=""#)).expect(name);
    let rest = &html[at + name.len() + 15..];
    rest[..rest.find('"').unwrap()].to_owned()
}

/// Signs in with `token`; returns the session cookie's value and its header.
pub(crate) async fn sign_in(app: &TestApp, token: &str) -> (String, String) {
    let c = browser();
    let form = c.get(app.url("/ui/login")).send().await.unwrap();
    let (login, _) = set_cookie(&form, "accelcal_login").expect("a sign-in cookie");
    let csrf = hidden(&form.text().await.unwrap(), "csrf");
    assert_eq!(csrf, login, "double submit: the form repeats the cookie");
    let res = c
        .post(app.url("/ui/login"))
        .header("cookie", format!("accelcal_login={login}"))
        .form(&[
            ("token", token),
            ("csrf", &csrf),
            ("next", "/ui/sensors/PAPER-2005"),
        ])
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::SEE_OTHER);
    assert_eq!(res.headers()[LOCATION], "/ui/sensors/PAPER-2005");
    set_cookie(&res, "accelcal_session").expect("a session cookie")
}

pub(crate) async fn page(app: &TestApp, path: &str, session: &str) -> reqwest::Response {
    browser()
        .get(app.url(path))
        .header("cookie", format!("accelcal_session={session}"))
        .send()
        .await
        .unwrap()
}

#[rstest]
#[tokio::test]
async fn pages_ask_to_sign_in_and_come_back(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let res = browser()
        .get(app.url("/ui/sensors?status=ok"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::SEE_OTHER);
    assert_eq!(
        res.headers()[LOCATION],
        "/ui/login?next=%2Fui%2Fsensors%3Fstatus%3Dok"
    );
    for (path, to) in [
        ("/", "/ui/sensors"),
        ("/ui", "/ui/sensors"),
        ("/ui/", "/ui/sensors"),
    ] {
        let res = browser().get(app.url(path)).send().await.unwrap();
        assert_eq!(
            (res.status(), res.headers()[LOCATION].to_str().unwrap()),
            (StatusCode::SEE_OTHER, to),
            "{path}"
        );
    }
    let reader = app.token("reader", None).await;
    app.submit(ADMIN, &paper()).await;
    let (session, header) = sign_in(&app, &reader).await;
    for attribute in ["HttpOnly", "SameSite=Strict", "Path=/ui"] {
        assert!(header.contains(attribute), "{header}");
    }
    assert!(
        !header.contains("Secure"),
        "plain http without a public https URL: {header}"
    );
    assert!(
        !header.contains("Max-Age"),
        "the server ends sessions, the browser forgets them on close: {header}"
    );
    let res = page(&app, "/ui/sensors/PAPER-2005", &session).await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.headers()[CONTENT_TYPE], "text/html; charset=utf-8");
    let csp = res.headers()["content-security-policy"]
        .to_str()
        .unwrap()
        .to_owned();
    assert!(
        csp.starts_with("default-src 'none'; style-src 'self'"),
        "{csp}"
    );
    assert!(
        csp.contains("script-src 'self'") && !csp.contains("unsafe"),
        "this origin's script, none inline: {csp}"
    );
    let html = res.text().await.unwrap();
    assert_eq!(
        html.matches("<script").count(),
        1,
        "the one script (ui_live.rs)"
    );
    assert!(!html.contains("style=\""), "no inline style");
    assert!(html.contains("PAPER-2005"));
    // The stylesheet the page names is served, cached for good under its hash.
    let at = html.find("/ui/assets/style-").unwrap();
    let href = &html[at..at + html[at..].find('"').unwrap()];
    let css = browser().get(app.url(href)).send().await.unwrap();
    assert_eq!(css.status(), StatusCode::OK);
    assert_eq!(
        css.headers()["cache-control"],
        "public, max-age=31536000, immutable"
    );
    assert_eq!(css.headers()[CONTENT_TYPE], "text/css; charset=utf-8");
}

#[rstest]
#[tokio::test]
async fn a_wrong_token_or_a_forged_form_gets_the_form_again(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let c = browser();
    let form = c.get(app.url("/ui/login")).send().await.unwrap();
    let (login, _) = set_cookie(&form, "accelcal_login").unwrap();
    let post = |token: &str, csrf: &str, cookie: Option<&str>| {
        let mut req = c
            .post(app.url("/ui/login"))
            .form(&[("token", token), ("csrf", csrf)]);
        if let Some(v) = cookie {
            req = req.header("cookie", format!("accelcal_login={v}"));
        }
        req.send()
    };
    let wrong = post("acc_not_a_token", &login, Some(&login)).await.unwrap();
    assert_eq!(wrong.status(), StatusCode::UNAUTHORIZED);
    assert_eq!(wrong.headers()[CONTENT_TYPE], "text/html; charset=utf-8");
    let html = wrong.text().await.unwrap();
    assert!(
        html.contains("That token was not accepted: the token is not valid."),
        "{html}"
    );
    assert!(html.contains(r#"name="token""#), "the form again");
    for (csrf, cookie) in [
        (login.as_str(), None),
        ("", Some(login.as_str())),
        ("forged", Some(login.as_str())),
    ] {
        let res = post(ADMIN, csrf, cookie).await.unwrap();
        assert_eq!(
            res.status(),
            StatusCode::FORBIDDEN,
            "csrf {csrf:?} cookie {cookie:?}"
        );
        assert!(set_cookie(&res, "accelcal_session").is_none());
        assert!(
            res.text()
                .await
                .unwrap()
                .contains("did not come from this site")
        );
    }
    let cross = c
        .post(app.url("/ui/login"))
        .header("cookie", format!("accelcal_login={login}"))
        .header("sec-fetch-site", "cross-site")
        .form(&[("token", ADMIN), ("csrf", login.as_str())])
        .send()
        .await
        .unwrap();
    assert_eq!(cross.status(), StatusCode::FORBIDDEN);
}

#[rstest]
#[tokio::test]
async fn only_pages_of_the_site_are_returned_to(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let c = browser();
    for next in [
        "https://evil.example/",
        "//evil.example/ui/",
        "/v1/tokens",
        "/ui/login",
    ] {
        let form = c.get(app.url("/ui/login")).send().await.unwrap();
        let (login, _) = set_cookie(&form, "accelcal_login").unwrap();
        let res = c
            .post(app.url("/ui/login"))
            .header("cookie", format!("accelcal_login={login}"))
            .form(&[("token", ADMIN), ("csrf", login.as_str()), ("next", next)])
            .send()
            .await
            .unwrap();
        assert_eq!(res.headers()[LOCATION], "/ui/sensors", "{next}");
    }
}

#[rstest]
#[tokio::test]
async fn sessions_end_on_expiry_revocation_and_sign_out(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::configured(engine, |c| {
        c.web = Web {
            public_url: Some("https://cal.example.com".into()),
            session_ttl: Duration::from_secs(1),
            ..Web::default()
        }
    })
    .await;
    let reader = app.token("reader", None).await;
    let (session, header) = sign_in(&app, &reader).await;
    assert!(
        header.contains("Secure"),
        "a public https URL makes cookies Secure: {header}"
    );
    assert_eq!(
        page(&app, "/ui/sensors", &session).await.status(),
        StatusCode::OK
    );
    tokio::time::sleep(Duration::from_millis(1300)).await;
    let res = page(&app, "/ui/sensors", &session).await;
    assert_eq!(res.status(), StatusCode::SEE_OTHER);
    assert!(
        res.headers()[LOCATION]
            .to_str()
            .unwrap()
            .ends_with("&reason=expired")
    );
    let again = browser()
        .get(app.url("/ui/login?reason=expired"))
        .send()
        .await
        .unwrap();
    assert!(
        again
            .text()
            .await
            .unwrap()
            .contains("Your session has expired")
    );

    // Revoking the token ends its sessions at once.
    let created: Value = app
        .post("/v1/tokens", ADMIN, &json!({"role": "reader"}))
        .await
        .json()
        .await
        .unwrap();
    // (A second server on the same database, with the default lifetime.)
    let app2 = TestApp::spawn_on(&app.database).await;
    let (s2, _) = sign_in(&app2, created["token"].as_str().unwrap()).await;
    assert_eq!(
        page(&app2, "/ui/sensors", &s2).await.status(),
        StatusCode::OK
    );
    app2.revoke(created["id"].as_str().unwrap()).await;
    let res = page(&app2, "/ui/sensors", &s2).await;
    assert!(
        res.headers()[LOCATION]
            .to_str()
            .unwrap()
            .ends_with("&reason=ended")
    );

    // Signing out needs the session's CSRF token, then ends it.
    let (s3, _) = sign_in(&app2, ADMIN).await;
    let html = page(&app2, "/ui/sensors", &s3).await.text().await.unwrap();
    assert!(html.contains("(configured admin token)"));
    let csrf = hidden(&html, "csrf");
    let out = |csrf: String| {
        browser()
            .post(app2.url("/ui/logout"))
            .header("cookie", format!("accelcal_session={s3}"))
            .form(&[("csrf", csrf)])
            .send()
    };
    assert_eq!(
        out(String::new()).await.unwrap().status(),
        StatusCode::FORBIDDEN
    );
    assert_eq!(
        out("x".repeat(43)).await.unwrap().status(),
        StatusCode::FORBIDDEN
    );
    assert_eq!(
        page(&app2, "/ui/sensors", &s3).await.status(),
        StatusCode::OK,
        "still signed in"
    );
    let res = out(csrf).await.unwrap();
    assert_eq!(res.headers()[LOCATION], "/ui/login?reason=signed-out");
    let cleared = set_cookie(&res, "accelcal_session").unwrap().1;
    assert!(cleared.contains("Max-Age=0"), "{cleared}");
    assert_eq!(
        page(&app2, "/ui/sensors", &s3).await.status(),
        StatusCode::SEE_OTHER
    );
}

#[rstest]
#[tokio::test]
async fn unknown_pages_and_calibrations_are_pages_not_problems(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let (session, _) = sign_in(&app, ADMIN).await;
    for path in [
        "/ui/nowhere",
        "/ui/calibrations/not-an-id",
        "/ui/sensors/NOPE",
        "/ui/assets/x.css",
    ] {
        let res = page(&app, path, &session).await;
        assert_eq!(res.status(), StatusCode::NOT_FOUND, "{path}");
        assert_eq!(
            res.headers()[CONTENT_TYPE],
            "text/html; charset=utf-8",
            "{path}"
        );
    }
    let res = page(&app, "/ui/sensors?status=sideways", &session).await;
    assert_eq!(res.status(), StatusCode::BAD_REQUEST);
    assert!(res.text().await.unwrap().contains("status"));
}

#[rstest]
#[tokio::test]
async fn the_certificate_is_verifiable(#[values(Sqlite, Postgres)] engine: Engine) {
    let dir = tempfile::tempdir().unwrap();
    let logo_path = dir.path().join("logo.svg");
    let logo_svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="10" height="10"/>"#;
    std::fs::write(&logo_path, logo_svg).unwrap();
    let logo = accelcal::startup::Laboratory::logo_from(&logo_path).unwrap();
    let app = TestApp::configured(engine, |c| {
        c.web.public_url = Some("https://cal.example.com/".into());
        c.web.laboratory = accelcal::startup::Laboratory {
            name: Some("Inertial Test Lab & Co.".into()),
            address: Some("Bahnhofstrasse 1, 8001 Zürich".into()),
            country: Some("CH".into()),
            accreditation: Some("SAS SCS 0999".into()),
            logo: Some(logo),
        };
    })
    .await;
    let mut received = paper();
    received["item_received_at"] = json!("2005-07-29T09:00:00Z");
    received["item_condition"] = json!("sealed in its shipping case");
    let body = serde_json::to_vec(&received).unwrap();
    let res = app
        .client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(ADMIN)
        .header(CONTENT_TYPE, "application/json")
        .body(body.clone())
        .send()
        .await
        .unwrap();
    let stored: Value = res.json().await.unwrap();
    // The method that computed it is recorded with it, and the certificate
    // says so.
    let method = serde_json::json!({
        "accelcal": env!("CARGO_PKG_VERSION"),
        "core": accelcal_core::VERSION,
    });
    assert_eq!(stored["method"], method);
    let id = stored["id"].as_str().unwrap();
    let again = app.get_json(&format!("/v1/calibrations/{id}"), ADMIN).await;
    assert_eq!(again["method"], method);
    let path = format!("/v1/calibrations/{id}/certificate");
    assert_eq!(
        app.client
            .get(app.url(&path))
            .send()
            .await
            .unwrap()
            .status(),
        StatusCode::UNAUTHORIZED
    );
    let reader = app.token("reader", None).await;
    let res = app.get(&path, &reader).await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.headers()[CONTENT_TYPE], "text/html; charset=utf-8");
    let csp = res.headers()["content-security-policy"]
        .to_str()
        .unwrap()
        .to_owned();
    let html = res.text().await.unwrap();
    // The inline stylesheet is exactly the one the policy allows.
    let style = &html[html.find("<style>").unwrap() + 7..html.find("</style>").unwrap()];
    use base64::Engine as _;
    let hash = base64::engine::general_purpose::STANDARD.encode(Sha256::digest(style.as_bytes()));
    assert!(csp.contains(&format!("style-src 'sha256-{hash}'")), "{csp}");
    assert!(html.contains("@page { size: A4"), "prints on A4");
    // What makes it verifiable, computed here independently.
    assert!(
        html.contains(&hex::encode(Sha256::digest(&body))),
        "the submission's SHA-256"
    );
    assert!(
        html.contains(&format!("https://cal.example.com{path}")),
        "its own URL"
    );
    assert!(html.contains(&format!(
        "Computed by</dt><dd>accelcal {} (core {})",
        env!("CARGO_PKG_VERSION"),
        accelcal_core::VERSION
    )));
    assert!(html.contains("PAPER-2005") && html.contains("k0, ki, kp"));
    // K1 to the place of its expanded uncertainty's second significant
    // digit (GUM 7.2.6), U to two digits, its unit, the coverage
    // probability beside k, the end marker.
    let ki = stored["fused"]["coefficients"]["ki"].as_f64().unwrap();
    let u = stored["uncertainty"]["terms"]["ki"]["expanded"]
        .as_f64()
        .unwrap();
    let decimals = (1 - u.log10().floor() as i32) as usize;
    assert!(
        html.contains(&format!(">{ki:.decimals$}<")) && html.contains(&format!(">{u:.decimals$}<")),
        "K1 {ki:.decimals$} ± {u:.decimals$}"
    );
    assert!(html.contains(">output/g<"), "the unit of K1");
    assert!(
        html.contains("k0 in output, ki in output/g, kp in output/g"),
        "the budget's units"
    );
    // Each coefficient's u_c, ν_eff, k and p beside U (issue 42), as the
    // stored result states them; the statement of the coverage; the scope.
    let b = &stored["uncertainty"]["terms"]["ki"];
    let k = format!("{:.2}", b["coverage_factor"].as_f64().unwrap());
    let k = k.trim_end_matches('0').trim_end_matches('.');
    let row = format!(
        "<td class=\"num\">{}</td><td class=\"num\">{k}</td><td class=\"num\">95.45 %</td>",
        b["effective_dof"]
    );
    assert!(html.contains(&row), "ki's coverage: {row}");
    assert!(html.contains("for a coverage probability of 95.45 %"));
    assert!(html.contains("The results relate only to the item calibrated"));
    assert!(html.contains(&format!("End of certificate No. {id}")));
    // Who issues it, and where it was calibrated; the logo as embedded,
    // which the policy allows.
    assert!(
        html.contains("Inertial Test Lab &amp; Co."),
        "the laboratory"
    );
    assert!(html.contains("Accredited: SAS SCS 0999"));
    assert!(html.contains("Item received</dt><dd>2005-07-29 09:00 UTC"));
    assert!(html.contains("Condition on receipt</dt><dd>sealed in its shipping case"));
    assert!(html.contains("Place of calibration</dt><dd>Bahnhofstrasse 1, 8001 Zürich"));
    let embedded = base64::engine::general_purpose::STANDARD.encode(logo_svg);
    assert!(html.contains(&format!("src=\"data:image/svg+xml;base64,{embedded}\"")));
    assert!(csp.contains("img-src data:"), "{csp}");
    assert_eq!(
        app.get(
            "/v1/calibrations/01a20000-0000-7000-8000-000000000000/certificate",
            &reader
        )
        .await
        .status(),
        StatusCode::NOT_FOUND
    );
    // The same certificate from the pages.
    let (session, _) = sign_in(&app, &reader).await;
    let from_ui = page(
        &app,
        &format!("/ui/calibrations/{id}/certificate"),
        &session,
    )
    .await
    .text()
    .await
    .unwrap();
    assert!(from_ui.contains(&hex::encode(Sha256::digest(&body))));
}

/// A submission of many cells: 1 000 runs (the most) of 200 positions, one
/// sample each (200 000 samples, about 2 MiB of JSON).
fn at_the_limits() -> Value {
    let positions: Vec<Value> = (0..200)
        .map(|i| {
            let th = i as f64 * std::f64::consts::TAU / 200.0;
            let r = |x: f64| (x * 1e9).round() / 1e9;
            serde_json::json!({"a": [r(th.cos()), r(th.sin()), 0.0]})
        })
        .collect();
    let runs: Vec<Value> = (0..1000)
        .map(|j| {
            let readings: Vec<Value> = (0..200)
                .map(|i| {
                    let th = i as f64 * std::f64::consts::TAU / 200.0;
                    let noise = 1e-6 * ((i * 7 + j * 13) as f64).sin();
                    let u = 1e-3 + 1.2 * th.cos() + 6e-3 * th.sin() + noise;
                    serde_json::json!([(u * 1e8).round() / 1e8])
                })
                .collect();
            serde_json::json!({ "readings": readings })
        })
        .collect();
    serde_json::json!({"sensor_id": "LIMITS-1", "positions": positions, "runs": runs})
}

/// Hardening round three, finding 7: every page is bounded whatever the
/// history's length or the submission's size. A sensor with 600
/// calibrations: its stability covers the latest 250 and counts the 350 it
/// leaves out, its page says so and stays small; a calibration at the input
/// limits (1 000 runs × 200 positions) gives a page of bounded size that
/// says what it does not show.
#[rstest]
#[tokio::test]
async fn pages_are_bounded_whatever_the_history(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let station = app.token("station", None).await;
    let mut lanes = tokio::task::JoinSet::new();
    for lane in 0..8 {
        let (client, url, station) = (
            app.client.clone(),
            app.url("/v1/calibrations"),
            station.clone(),
        );
        lanes.spawn(async move {
            for k in (lane..600).step_by(8) {
                let mut body = accelcal_testkit::submission("LONG-1", "2020-01-01T00:00:00Z", 4);
                body["performed_at"] = serde_json::json!(format!(
                    "{}-{:02}-{:02}T00:00:{:02}Z",
                    2000 + k / 300,
                    1 + (k / 25) % 12,
                    1 + k % 25,
                    k % 60
                ));
                let res = client
                    .post(&url)
                    .bearer_auth(&station)
                    .json(&body)
                    .send()
                    .await
                    .unwrap();
                assert_eq!(res.status(), StatusCode::CREATED);
            }
        });
    }
    while let Some(done) = lanes.join_next().await {
        done.unwrap();
    }
    let stability: Value = app
        .get("/v1/sensors/LONG-1/stability", &station)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(stability["calibrations"], 250, "{stability}");
    assert_eq!(stability["omitted"], 350, "{stability}");
    let (session, _) = sign_in(&app, &station).await;
    let res = page(&app, "/ui/sensors/LONG-1", &session).await;
    assert_eq!(res.status(), StatusCode::OK);
    let html = res.text().await.unwrap();
    assert!(
        html.contains("the latest 250 of the window's 600 calibrations"),
        "no cap notice"
    );
    eprintln!("sensor page with 600 calibrations: {} bytes", html.len());
    assert!(html.len() < 800_000, "{} bytes", html.len());

    let limits = at_the_limits();
    let body = serde_json::to_vec(&limits).unwrap();
    assert!(body.len() < 4 * 1024 * 1024);
    let res = app
        .client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(&station)
        .header("content-type", "application/json")
        .body(body)
        .send()
        .await
        .unwrap();
    let status = res.status();
    let stored: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{stored}");
    let id = stored["id"].as_str().unwrap();
    let res = page(&app, &format!("/ui/calibrations/{id}"), &session).await;
    assert_eq!(res.status(), StatusCode::OK);
    let html = res.text().await.unwrap();
    eprintln!("calibration page at the input limits: {} bytes", html.len());
    assert!(html.len() < 800_000, "{} bytes", html.len());
    assert!(
        html.contains("Runs 25–1000 are not shown here"),
        "per-run table note"
    );
    assert!(
        html.contains("Runs 11–1000 are not shown here"),
        "residuals note"
    );
    assert!(!html.contains(r#"data-run="24""#));
}

/// A single run, and a misfit: the calibration page and the certificate
/// render them — no batches and no eq. 8 for the one, the lack-of-fit and
/// unmodelled-term warnings and the budget's model column for the other.
#[rstest]
#[tokio::test]
async fn single_runs_and_misfits_are_shown(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let mut one = paper();
    one["runs"] = json!([one["runs"][0]]);
    one["sensor_id"] = json!("ONE-RUN");
    let r = app.submit(ADMIN, &one).await;
    assert_eq!(r["fused"]["batches"], json!([]));
    assert!(r["fused"]["dispersion"].is_null() && r["mean"]["dispersion"].is_null());
    assert!(
        r["fused"]["note"]
            .as_str()
            .unwrap()
            .starts_with("a single run")
    );
    let id = r["id"].as_str().unwrap().to_owned();
    let reader = app.token("reader", None).await;
    let (session, _) = sign_in(&app, &reader).await;
    let res = page(&app, &format!("/ui/calibrations/{id}"), &session).await;
    assert_eq!(res.status(), StatusCode::OK);
    let html = res.text().await.unwrap();
    assert!(html.contains("Not fused: a single run"), "no note");
    let res = page(
        &app,
        &format!("/ui/calibrations/{id}/certificate"),
        &session,
    )
    .await;
    assert_eq!(res.status(), StatusCode::OK);

    let misfit = misfit_submission("MISFIT-2");
    let id = app.submit(ADMIN, &misfit).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let html = page(&app, &format!("/ui/calibrations/{id}"), &session)
        .await
        .text()
        .await
        .unwrap();
    for text in [
        "Lack of fit.",
        "Unmodelled term.",
        "<code>kii</code>",
        "data-label=\"Model\"",
        "Lack-of-fit test: F =",
    ] {
        assert!(html.contains(text), "no {text}");
    }
    let cert = page(
        &app,
        &format!("/ui/calibrations/{id}/certificate"),
        &session,
    )
    .await
    .text()
    .await
    .unwrap();
    assert!(
        cert.contains("the model's own standard error"),
        "certificate method"
    );
    assert!(cert.contains("data-label=\"Model\""), "certificate budget");
}

/// The review form on a calibration's page: a reviewer signs with the
/// session's token typed again; the page and the certificate then show the
/// signature, and a withdrawn calibration's certificate says so in its
/// running header (on every printed page).
#[rstest]
#[tokio::test]
async fn a_reviewer_signs_on_the_page(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let id = app.submit(ADMIN, &paper()).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let other = app.held_token("reviewer", "Olga Other", None).await;
    let reader = app.token("reader", None).await;
    let path = format!("/ui/calibrations/{id}");

    // A reader sees the state, and no form.
    let (session, _) = sign_in(&app, &reader).await;
    let html = page(&app, &path, &session).await.text().await.unwrap();
    assert!(html.contains(r#"<section id="review""#), "{html}");
    assert!(html.contains("Not reviewed yet."));
    assert!(!html.contains(r#"action="/ui/calibrations/"#));

    let (session, _) = sign_in(&app, &rita).await;
    let html = page(&app, &path, &session).await.text().await.unwrap();
    assert!(html.contains(&format!(r#"action="/ui/calibrations/{id}/review""#)));
    let csrf = hidden(&html, "csrf");
    let sign = |form: Vec<(&'static str, String)>| {
        browser()
            .post(app.url(&format!("{path}/review")))
            .header("cookie", format!("accelcal_session={session}"))
            .form(&form)
            .send()
    };
    // Another reviewer's token, no token, or no CSRF value: refused.
    for (token, csrf) in [
        (&other, &csrf),
        (&String::new(), &csrf),
        (&rita, &String::new()),
    ] {
        let res = sign(vec![
            ("act", "approve".into()),
            ("token", token.clone()),
            ("csrf", csrf.clone()),
        ])
        .await
        .unwrap();
        assert!(res.status().is_client_error(), "{}", res.status());
    }
    let res = sign(vec![
        ("act", "approve".into()),
        ("comment", "Residuals checked.".into()),
        ("token", rita.clone()),
        ("csrf", csrf.clone()),
    ])
    .await
    .unwrap();
    assert_eq!(res.status(), StatusCode::SEE_OTHER);
    assert_eq!(res.headers()[LOCATION], format!("{path}#review"));
    let html = page(&app, &path, &session).await.text().await.unwrap();
    assert!(html.contains(r#"<tr data-action="approve">"#), "{html}");
    assert!(html.contains("Rita Reviewer") && html.contains("Residuals checked."));
    let cert = page(&app, &format!("{path}/certificate"), &session)
        .await
        .text()
        .await
        .unwrap();
    assert!(cert.contains("Review and signatures") && cert.contains("Rita Reviewer"));
    assert!(!cert.contains("WITHDRAWN"));

    // Withdrawn without a reason: 422, nothing signed; with one, the
    // certificate's running header says so.
    let res = sign(vec![
        ("act", "withdraw".into()),
        ("token", rita.clone()),
        ("csrf", csrf.clone()),
    ])
    .await
    .unwrap();
    assert_eq!(res.status(), StatusCode::UNPROCESSABLE_ENTITY);
    let res = sign(vec![
        ("act", "withdraw".into()),
        ("comment", "Stand found out of level.".into()),
        ("token", rita.clone()),
        ("csrf", csrf),
    ])
    .await
    .unwrap();
    assert_eq!(res.status(), StatusCode::SEE_OTHER);
    let cert = page(&app, &format!("{path}/certificate"), &session)
        .await
        .text()
        .await
        .unwrap();
    let header = &cert[cert.find("<thead>").unwrap()..cert.find("</thead>").unwrap()];
    assert!(
        header.contains("WITHDRAWN") && header.contains("Stand found out of level."),
        "{header}"
    );
    let html = page(&app, &path, &session).await.text().await.unwrap();
    assert!(
        !html.contains(&format!(r#"action="/ui/calibrations/{id}/review""#)),
        "final"
    );
    // The reviewer sees the calibration's own audit trail: stored, approved,
    // withdrawn, each by whom; a reader does not.
    let trail = &html[html.find(r#"<table id="audit">"#).expect("a trail")..];
    let rows: Vec<&str> = trail
        .match_indices(r#"<tr data-action=""#)
        .map(|(i, m)| trail[i + m.len()..].split('"').next().unwrap())
        .collect();
    assert_eq!(
        rows,
        [
            "calibration.submitted",
            "calibration.approve",
            "calibration.withdraw"
        ]
    );
    assert!(trail.contains("Rita Reviewer"));
    let (session, _) = sign_in(&app, &reader).await;
    let html = page(&app, &path, &session).await.text().await.unwrap();
    assert!(!html.contains(r#"id="audit""#));
}
