//! Hardening round four (issue 43): a recording bounded like every other
//! input, triad refusals that name their cause, equal runs floored rather
//! than refused, `noisy_run` from the scatter the runs have, and the small
//! lines (stability's basis, the audit's actor filter).

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

use crate::triad::{recording, recording_refused, spiral, triad};

/// 400 orientations held 1 s each: more positions than any tumble may
/// have, refused with how many and what to raise; the detector's settings
/// below their minimums are refused by name.
#[tokio::test]
async fn a_recording_counts_against_the_position_limit() {
    let app = TestApp::spawn(Sqlite).await;
    let detector = json!({"still_s": 0.5, "window_s": 0.2, "threshold": 2, "min_static_s": 0.5});
    let samples = recording(&spiral(400), 1.0);
    let detail = recording_refused(
        &app,
        json!({"rate_hz": 50, "samples": samples, "detector": detector}),
    )
    .await;
    assert!(
        detail.contains("400 static intervals found, at most 360")
            && detail.contains("detector.min_static_s")
            && detail.contains("detector.threshold"),
        "{detail}"
    );
    // The same holds counted as 360 or fewer are computed.
    let samples = recording(&spiral(300), 1.0);
    let res = triad(
        &app,
        &json!({"unit": "g", "recording": {"rate_hz": 50, "samples": samples, "detector": detector}}),
    )
    .await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["detection"]["intervals"].as_array().unwrap().len(), 300);

    // Below the minimums: each setting named, the window also in samples.
    let low = json!({"still_s": 0.1, "window_s": 0.01, "threshold": 1.0, "min_static_s": 0.05});
    let p = problem(
        triad(
            &app,
            &json!({"recording": {"rate_hz": 50, "samples": recording(&spiral(12), 4.0), "detector": low}}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(
        pointers(&p),
        [
            "/recording/detector/still_s",
            "/recording/detector/window_s",
            "/recording/detector/threshold",
            "/recording/detector/min_static_s",
        ],
        "{p}"
    );
    // A window at its minimum in seconds is still ten samples or more: at
    // 50 Hz, 0.1 s is five.
    let short = json!({"window_s": 0.1});
    let p = problem(
        triad(
            &app,
            &json!({"recording": {"rate_hz": 50, "samples": recording(&spiral(12), 4.0), "detector": short}}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/recording/detector/window_s"], "{p}");
    assert!(p.to_string().contains("holds 5 samples at 50 Hz"), "{p}");
    assert!(
        p.to_string().contains("at least 10 (at least 0.2 s)"),
        "{p}"
    );
}

/// `n` directions within `half` degrees of `axis`, on a golden-angle
/// spiral over the cap.
fn cone(axis: [f64; 3], half: f64, n: usize) -> Vec<[f64; 3]> {
    let a = axis;
    let norm = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let a = a.map(|x| x / norm);
    let p = if a[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let cross = |u: [f64; 3], v: [f64; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let e1 = cross(a, p);
    let l = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).sqrt();
    let e1 = e1.map(|x| x / l);
    let e2 = cross(a, e1);
    (0..n)
        .map(|k| {
            let th = half.to_radians() * ((k as f64 + 0.5) / n as f64).sqrt();
            let ph = k as f64 * 2.399_963_229_728_653;
            [0, 1, 2].map(|m| a[m] * th.cos() + (e1[m] * ph.cos() + e2[m] * ph.sin()) * th.sin())
        })
        .collect()
}

/// A cone, a plane and a tilted plane are refused as the geometry they
/// are, never as a solver's non-convergence.
#[tokio::test]
async fn every_triad_refusal_names_its_cause() {
    let app = TestApp::spawn(Sqlite).await;
    let mut cases: Vec<(String, Vec<[f64; 3]>)> = Vec::new();
    for (k, half) in [5.0, 10.0, 15.0, 20.0, 30.0].into_iter().enumerate() {
        let axis = [[0.3, -0.5, 0.8], [1.0, 0.2, 0.1], [-0.4, 0.9, 0.2]][k % 3];
        cases.push((format!("cone {half}°"), cone(axis, half, 20)));
    }
    let plane: Vec<[f64; 3]> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::PI / 6.0;
            [a.cos(), a.sin(), 0.0]
        })
        .collect();
    cases.push(("plane".into(), plane));
    let tilted: Vec<[f64; 3]> = (0..12)
        .map(|k| {
            let a = k as f64 * std::f64::consts::PI / 6.0;
            let e = (if k % 2 == 0 { 3f64 } else { -3.0 }).to_radians();
            [a.cos() * e.cos(), a.sin() * e.cos(), e.sin()]
        })
        .collect();
    cases.push(("within 3° of a plane".into(), tilted));
    for (name, dirs) in cases {
        let body = json!({"unit": "g", "static_positions": crate::triad::positions_at(&dirs, 7)});
        let p = problem(triad(&app, &body).await, StatusCode::UNPROCESSABLE_ENTITY).await;
        assert_eq!(pointers(&p), ["/static_positions"], "{name}: {p}");
        let detail = p["errors"][0]["detail"].as_str().unwrap();
        assert!(
            detail.contains("the orientations do not span the sphere")
                && detail.contains("turn the triad about more than one axis"),
            "{name}: {detail}"
        );
    }
}

fn paper() -> Value {
    serde_json::from_str(include_str!("../../examples/paper-table1.json")).unwrap()
}

async fn identify(app: &TestApp, body: &Value) -> reqwest::Response {
    app.post("/v1/identify", ADMIN, body).await
}

fn kinds(r: &Value) -> Vec<String> {
    r["quality"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["kind"].as_str().unwrap().to_owned())
        .collect()
}

/// Runs 3–5 (the second batch) read the same position means — each run's
/// two samples in another order, so no run is a copy — and so give equal
/// coefficients: weighted at the floor and warned about, as runs that
/// differ a little are; a run sent twice is refused as a copy, naming both.
#[tokio::test]
async fn equal_runs_are_floored_and_only_a_copy_is_refused() {
    let app = TestApp::spawn(Sqlite).await;
    let mut body = paper();
    // Runs 4 and 5: run 3's samples, each position's two in the other
    // order at positions 0–1 (run 4) or 2–3 (run 5): a + b = b + a, so the
    // same means and exactly equal coefficients, yet no run is a copy.
    let third = body["runs"][3].clone();
    for (run, swapped) in [(4, [0, 1]), (5, [2, 3])] {
        let mut r = third.clone();
        for i in swapped {
            r["readings"][i].as_array_mut().unwrap().reverse();
        }
        body["runs"][run] = r;
    }
    let res = identify(&app, &body).await;
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{r}");
    let floored: Vec<&Value> = r["quality"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|w| w["kind"] == "implausibly_consistent_batch")
        .collect();
    assert!(!floored.is_empty(), "{r}");
    for w in &floored {
        assert_eq!(w["batch"], 1, "{w}");
        assert_eq!(w["std"], 0.0, "{w}");
        assert!(w["floor"].as_f64().unwrap() > 0.0, "{w}");
    }
    for v in r["fused"]["std_errors"].as_object().unwrap().values() {
        assert!(v.as_f64().unwrap() > 0.0, "{r}");
    }

    let mut copy = paper();
    copy["runs"][4] = copy["runs"][1].clone();
    let p = problem(
        identify(&app, &copy).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/runs/4"], "{p}");
    let detail = p["errors"][0]["detail"].as_str().unwrap();
    assert!(detail.contains("run 4 is a copy of run 1"), "{detail}");
}

/// The paper's data with run 4's samples 30 times as far apart about the
/// same means: the residuals cannot see it (one degree of freedom a run),
/// the samples' own scatter can; the warning says which test it used.
#[tokio::test]
async fn a_run_noisy_in_its_samples_is_found_by_its_pure_error() {
    let app = TestApp::spawn(Sqlite).await;
    let clean: Value = identify(&app, &paper()).await.json().await.unwrap();
    assert!(!kinds(&clean).contains(&"noisy_run".to_owned()), "{clean}");
    let mut body = paper();
    for reading in body["runs"][4]["readings"].as_array_mut().unwrap() {
        let r = reading.as_array_mut().unwrap();
        let (a, b) = (r[0].as_f64().unwrap(), r[1].as_f64().unwrap());
        let (m, h) = ((a + b) / 2.0, (b - a) / 2.0);
        r[0] = json!(m - 30.0 * h);
        r[1] = json!(m + 30.0 * h);
    }
    let r: Value = identify(&app, &body).await.json().await.unwrap();
    let noisy: Vec<&Value> = r["quality"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|w| w["kind"] == "noisy_run")
        .collect();
    assert_eq!(noisy.len(), 1, "{r}");
    let w = noisy[0];
    assert_eq!(w["run"], 4);
    assert_eq!(w["test"], "pure_error");
    assert_eq!((w["df1"].clone(), w["df2"].clone()), (json!(4), json!(20)));
    // F is the ratio of the variances: run 4's pure error against the
    // others pooled, from the samples by hand.
    let pe = |run: &Value, scale: f64| -> f64 {
        run["readings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| {
                let d = scale * (r[1].as_f64().unwrap() - r[0].as_f64().unwrap());
                d * d / 2.0
            })
            .sum()
    };
    let runs = paper()["runs"].clone();
    let own = pe(&runs[4], 30.0) / 4.0;
    let others: f64 = [0, 1, 2, 3, 5]
        .iter()
        .map(|j| pe(&runs[*j], 1.0))
        .sum::<f64>()
        / 20.0;
    let f = w["f"].as_f64().unwrap();
    assert!(
        (f - own / others).abs() < 1e-6 * f,
        "{f} against {}",
        own / others
    );
    assert!(w["p_value"].as_f64().unwrap() < 0.01 / 6.0);
    assert!(w["pure_error_std"].as_f64().unwrap() > w["others_pure_error_std"].as_f64().unwrap());
}

/// `?actor=` takes a token's id as `/v1/tokens` writes it (with hyphens),
/// or without them, as well as a holder's name.
#[tokio::test]
async fn the_audit_finds_a_token_by_the_id_tokens_gives() {
    let app = TestApp::spawn(Sqlite).await;
    let created: Value = app
        .post(
            "/v1/tokens",
            ADMIN,
            &json!({"role": "admin", "holder": "Ada Admin"}),
        )
        .await
        .json()
        .await
        .unwrap();
    let id = created["id"].as_str().unwrap().to_owned();
    assert!(id.contains('-'), "{created}");
    let secret = created["token"].as_str().unwrap();
    let res = app
        .put(
            "/v1/customers/ACME",
            secret,
            &json!({"name": "Acme Navigation GmbH", "address": "1 Gyro Way, 80331 Munich"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    for actor in [
        id.clone(),
        id.replace('-', ""),
        id.to_uppercase(),
        "Ada%20Admin".into(),
    ] {
        let found = app
            .get_json(&format!("/v1/audit?actor={actor}"), ADMIN)
            .await;
        let actions: Vec<&str> = found["items"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["action"].as_str().unwrap())
            .collect();
        assert_eq!(actions, ["customer.put"], "{actor}: {found}");
    }
}
