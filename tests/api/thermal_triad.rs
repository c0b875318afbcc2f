//! A triad's `b` and `S` over temperature (issue 45 item 1),
//! `POST /v1/identify/thermal/triad`: six-face tumbles at five chamber set
//! points with planted temperature models come back with each set point
//! calibrated exactly as `POST /v1/identify/triad` calibrates its runs
//! alone, each element's polynomial the weighted least-squares fit
//! (computed here by the normal equations, [`crate::thermal`]) of the
//! planted degree, and every refusal naming what to fix.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

use crate::thermal::is_the_weighted_fit;

/// The chamber's set points, °C (their mean, the reference, is 20).
pub const CHAMBER: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];

/// The planted triad at `t` °C: `b` (m/s², x quadratic, y linear, z
/// constant) and `S` (m/s² per g: the scale factors linear, the rest
/// constant).
fn planted(t: f64) -> ([f64; 3], [[f64; 3]; 3]) {
    planted_with(t, 1.0)
}

/// [`planted`] with the scale factors' temperature coefficients times
/// `scale_tc` (0: `S` constant).
pub fn planted_with(t: f64, scale_tc: f64) -> ([f64; 3], [[f64; 3]; 3]) {
    let dt = t - 20.0;
    let (sx, sy, sz) = (1e-4 * scale_tc, -5e-5 * scale_tc, 2e-4 * scale_tc);
    let b = [0.05 + 1e-3 * dt + 2e-5 * dt * dt, -0.03 + 5e-4 * dt, 0.02];
    let s = [
        [9.81 * (1.0 + sx * dt), 0.002, -0.001],
        [0.0015, 9.79 * (1.0 + sy * dt), 0.003],
        [-0.002, 0.001, 9.83 * (1.0 + sz * dt)],
    ];
    (b, s)
}

/// A deterministic deviate in (−1, 1) for `k`.
pub(crate) fn jitter(k: u64) -> f64 {
    let x = k.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(23) ^ 0x2545_f491_4f6c_dd1d;
    (x % 2_000_001) as f64 / 1_000_000.0 - 1.0
}

const FACES: [[f64; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
];

/// Ten runs at each of `set_points` (fused in two batches of five: a
/// batch's variance from two runs has one degree of freedom, and the
/// weights 1/se² then follow its luck more than the noise), two samples
/// a face, each run within ±0.02 K of its set point, noise 2e-4 m/s².
pub fn body(set_points: &[f64]) -> Value {
    body_with(set_points, 1.0)
}

/// [`body`] of [`planted_with`]`(·, scale_tc)`.
pub fn body_with(set_points: &[f64], scale_tc: f64) -> Value {
    let mut runs = Vec::new();
    for (sp, &t) in set_points.iter().enumerate() {
        for r in 0..10u64 {
            let k = (sp as u64) * 1000 + r * 100;
            let temperature = t + 0.02 * jitter(k);
            let (b, s) = planted_with(temperature, scale_tc);
            let samples: Vec<Value> = FACES
                .iter()
                .enumerate()
                .map(|(p, g)| {
                    let u = |n: u64| -> Vec<f64> {
                        (0..3)
                            .map(|m| {
                                b[m] + (0..3).map(|c| s[m][c] * g[c]).sum::<f64>()
                                    + 2e-4 * jitter(k + 10 * p as u64 + 3 * n + m as u64 + 1)
                            })
                            .collect()
                    };
                    json!([u(0), u(1)])
                })
                .collect();
            runs.push(json!({"samples": samples, "temperature_c": temperature}));
        }
    }
    json!({"sensor_id": "IMU-T", "unit": "m/s2", "orientations": "six_faces",
           "runs": runs, "batches": 2})
}

/// Element `m` of `b` (`n` none) or `(m, n)` of `S` of the model `r` is
/// the weighted fit of its set points' values (the normal equations,
/// [`is_the_weighted_fit`]) and holds `at_tref` at `T_ref` within four
/// standard uncertainties.
pub(crate) fn fits_its_set_points(r: &Value, m: usize, n: Option<usize>, at_tref: f64) {
    let set_points = r["set_points"].as_array().unwrap();
    let t: Vec<f64> = set_points.iter().map(|s| f(&s["temperature_c"])).collect();
    let (pointer, values, errors) = match n {
        None => (format!("/b/{m}"), "b", "b_std_errors"),
        Some(k) => (format!("/S/{m}/{k}"), "S", "S_std_errors"),
    };
    let of = |sp: &Value, key: &str| match n {
        None => f(&sp[key][m]),
        Some(k) => f(&sp[key][m][k]),
    };
    let c: Vec<f64> = set_points.iter().map(|sp| of(sp, values)).collect();
    let u: Vec<f64> = set_points.iter().map(|sp| of(sp, errors)).collect();
    let p = r.pointer(&pointer).unwrap();
    is_the_weighted_fit(p, &t, &c, &u, &pointer);
    assert!(
        (f(&p["coefficients"][0]) - at_tref).abs() < 4.0 * f(&p["std_uncertainties"][0]),
        "{pointer} at T_ref: {} against {at_tref}",
        p["coefficients"][0]
    );
}

/// `b` posted to `path`, refused with 422: its problem.
pub(crate) async fn refused(app: &TestApp, b: Value, path: &str) -> Value {
    problem(
        app.post(path, ADMIN, &b).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await
}

pub fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

#[tokio::test]
async fn five_set_points_give_each_element_its_planted_degree() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    let res = app.post("/v1/identify/thermal/triad", ADMIN, &b).await;
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{r}");
    crate::conforms_to("TriadThermalModel", &r);
    assert_eq!(
        (r["sensor_id"].as_str(), r["unit"].as_str()),
        (Some("IMU-T"), Some("m/s2"))
    );

    // Five set points of ten runs, coolest first; each calibrated as
    // POST /v1/identify/triad calibrates its runs alone (without their
    // temperatures).
    let set_points = r["set_points"].as_array().unwrap();
    assert_eq!(set_points.len(), 5);
    for (s, sp) in set_points.iter().enumerate() {
        let runs: Vec<usize> = sp["runs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| j.as_u64().unwrap() as usize)
            .collect();
        assert_eq!(runs, (10 * s..10 * s + 10).collect::<Vec<_>>());
        assert!((f(&sp["temperature_c"]) - CHAMBER[s]).abs() < 0.02);
        let mut alone = b.clone();
        alone["runs"] = json!(
            runs.iter()
                .map(|&j| json!({"samples": b["runs"][j]["samples"].clone()}))
                .collect::<Vec<_>>()
        );
        let res = app.post("/v1/identify/triad", ADMIN, &alone).await;
        assert_eq!(res.status(), StatusCode::OK);
        let one: Value = res.json().await.unwrap();
        for key in ["b", "b_std_errors", "S", "S_std_errors"] {
            assert_eq!(sp[key], one[key], "set point {s}: {key}");
        }
        assert_eq!(sp["batches"], 2);
    }

    // Each element: T_ref 20 °C; the weighted fit the normal equations
    // give at its degree, its covariance inflated by max(1, χ²/ν); and
    // the planted degree where the temperature moves it (b_x quadratic,
    // b_y and the scale factors linear). An element planted constant gets
    // the degree its own partial F tests give: on five set points the test
    // has at most three degrees of freedom below, and calls a constant
    // linear when the linear fit's χ² is small by chance.
    let b_degrees = [2, 1, 0];
    let (b_ref, s_ref) = planted(20.0);
    let mut elements = Vec::new();
    for (m, row) in s_ref.iter().enumerate() {
        elements.push((format!("/b/{m}"), b_degrees[m], b_ref[m], m, None));
        for (n, &value) in row.iter().enumerate() {
            // The scale factors move with the temperature; the rest not.
            let degree = usize::from(m == n);
            elements.push((format!("/S/{m}/{n}"), degree, value, m, Some(n)));
        }
    }
    for (pointer, degree, at_tref, m, n) in elements {
        let p = r.pointer(&pointer).unwrap();
        let tests = p["selection"].as_array().unwrap();
        let chosen = p["degree"].as_u64().unwrap() as usize;
        let planted_degree = degree;
        if planted_degree > 0 {
            assert_eq!(chosen, planted_degree, "{pointer}: {p}");
        } else {
            // Backward from degree 3 while the highest term is not
            // significant at 1 %; the first significant one stays.
            let kept = tests.iter().position(|t| f(&t["p_value"]) < 0.01);
            assert_eq!(chosen, kept.map_or(0, |k| 3 - k), "{pointer}: {p}");
            assert_eq!(tests.len(), kept.map_or(3, |k| k + 1), "{pointer}: {p}");
        }
        let degree = chosen;
        let tref = f(&p["reference_c"]);
        assert_eq!(tref, 20.0);
        fits_its_set_points(&r, m, n, at_tref);
        assert_eq!(p["range_c"][0], set_points[0]["temperature_c"]);
        assert_eq!(p["range_c"][1], set_points[4]["temperature_c"]);
        // The planted value at T_ref within four standard uncertainties,
        // and any slope of a constant element within four of zero.
        if planted_degree == 0 {
            for d in 1..=degree {
                assert!(
                    f(&p["coefficients"][d]).abs() < 4.0 * f(&p["std_uncertainties"][d]),
                    "{pointer} a_{d}: {p}"
                );
            }
        }
    }
    // The planted slopes of b_x and S_zz.
    let slope = |pointer: &str| {
        let p = r.pointer(pointer).unwrap();
        (f(&p["coefficients"][1]), f(&p["std_uncertainties"][1]))
    };
    let (a1, u1) = slope("/b/0");
    assert!((a1 - 1e-3).abs() < 4.0 * u1, "{a1} ± {u1}");
    let (a1, u1) = slope("/S/2/2");
    assert!((a1 - 9.83 * 2e-4).abs() < 4.0 * u1, "{a1} ± {u1}");
}

#[tokio::test]
async fn refusals_name_what_to_fix() {
    let app = TestApp::spawn(Sqlite).await;
    let thermal = "/v1/identify/thermal/triad";
    let pointer = |p: &Value| p["errors"][0]["pointer"].as_str().unwrap().to_owned();

    // One run without its temperature.
    let mut b = body(&CHAMBER);
    b["runs"][3]
        .as_object_mut()
        .unwrap()
        .remove("temperature_c");
    let p = refused(&app, b, thermal).await;
    assert_eq!(pointer(&p), "/runs/3/temperature_c", "{p}");
    // A temperature no instrument reads.
    let mut b = body(&CHAMBER);
    b["runs"][0]["temperature_c"] = json!(300.0);
    let p = refused(&app, b, thermal).await;
    assert_eq!(pointer(&p), "/runs/0/temperature_c", "{p}");
    assert!(
        p["detail"].as_str().unwrap().contains("-100 to 200 °C"),
        "{p}"
    );
    // None at all.
    let mut b = body(&CHAMBER);
    for run in b["runs"].as_array_mut().unwrap() {
        run.as_object_mut().unwrap().remove("temperature_c");
    }
    let p = refused(&app, b, thermal).await;
    assert_eq!(pointer(&p), "/runs/0/temperature_c", "{p}");
    // One set point: one more to add; a 4 K span: where to add one.
    let p = refused(&app, body(&[20.0]), thermal).await;
    assert_eq!(pointer(&p), "/runs", "{p}");
    let detail = p["detail"].as_str().unwrap();
    assert!(detail.contains("add 1 more"), "{p}");
    let p = refused(&app, body(&[20.0, 22.0, 24.0]), thermal).await;
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("add a set point at or below 14 °C or at or above 29.99 °C"),
        "{p}"
    );
    // Static positions without their temperatures; second-order terms:
    // not modelled.
    let p = refused(
        &app,
        json!({"unit": "m/s2", "static_positions": vec![vec![[0.0, 0.0, 9.8]]; 9]}),
        thermal,
    )
    .await;
    assert_eq!(pointer(&p), "/static_temperatures_c", "{p}");
    let mut b = body(&CHAMBER);
    b["second_order"] = json!(true);
    assert_eq!(pointer(&refused(&app, b, thermal).await), "/second_order");
    // Runs at several temperatures sent to the plain triad calibration:
    // pointed here rather than the temperatures ignored, at the reading
    // farthest from their mean (35 °C): the hottest, one of the ten runs at
    // 60 °C (runs 20 to 29).
    let whole = body(&[20.0, 25.0, 60.0]);
    let temperature = |j: usize| f(&whole["runs"][j]["temperature_c"]);
    let hottest = (20..30)
        .max_by(|&a, &b| temperature(a).total_cmp(&temperature(b)))
        .unwrap();
    let p = refused(&app, whole, "/v1/identify/triad").await;
    assert_eq!(pointer(&p), format!("/runs/{hottest}/temperature_c"), "{p}");
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("/v1/identify/thermal/triad"),
        "{p}"
    );
    // A parameter out of range: 400 naming it.
    let p = problem(
        app.post(
            "/v1/identify/thermal/triad?degree=4",
            ADMIN,
            &body(&CHAMBER),
        )
        .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "degree", "{p}");
}

/// A chamber that drifts during a run: each run's `temperature_c` one per
/// position gives the model of the same runs each at its positions' mean
/// (computed here), to the last bit, fitted and stored; a run drifting more
/// than the tolerance, a wrong count and an implausible reading are
/// refused where they are.
#[tokio::test]
async fn a_drifting_chamber_gives_each_position_its_temperature() {
    let app = TestApp::spawn(Sqlite).await;
    let steady_at = body(&CHAMBER);
    let (mut drifting, mut steady) = (steady_at.clone(), steady_at.clone());
    let drift = [-0.1, -0.06, -0.02, 0.03, 0.07, 0.12];
    for j in 0..drifting["runs"].as_array().unwrap().len() {
        let t = f(&steady_at["runs"][j]["temperature_c"]);
        let each: Vec<f64> = drift.iter().map(|d| t + d).collect();
        steady["runs"][j]["temperature_c"] = json!(each.iter().sum::<f64>() / 6.0);
        drifting["runs"][j]["temperature_c"] = json!(each);
    }
    let fit = |b: Value| {
        let app = &app;
        async move {
            let res = app.post("/v1/identify/thermal/triad", ADMIN, &b).await;
            assert_eq!(res.status(), StatusCode::OK);
            res.json::<Value>().await.unwrap()
        }
    };
    let (got, want) = (fit(drifting.clone()).await, fit(steady).await);
    assert_eq!(got, want);
    assert_ne!(
        got["set_points"][0]["temperature_c"],
        fit(steady_at).await["set_points"][0]["temperature_c"],
        "the means, not the runs' nominal temperatures"
    );
    let res = app
        .post("/v1/calibrations/thermal/triad", ADMIN, &drifting)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    assert_eq!(res.json::<Value>().await.unwrap()["thermal"], got);

    let mut far = drifting.clone();
    far["runs"][3]["temperature_c"][5] = json!(f(&far["runs"][3]["temperature_c"][0]) + 0.7);
    let p = refused(&app, far, "/v1/identify/thermal/triad").await;
    assert_eq!(pointers(&p), ["/runs/3/temperature_c"], "{p}");
    assert!(p["detail"].as_str().unwrap().contains("drifted"), "{p}");
    let mut five = drifting.clone();
    five["runs"][0]["temperature_c"] = json!([20.0, 20.1, 20.2, 20.3, 20.4]);
    let p = refused(&app, five, "/v1/identify/thermal/triad").await;
    assert_eq!(pointers(&p), ["/runs/0/temperature_c"], "{p}");
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("one per position (6)")
    );
    let mut hot = drifting.clone();
    hot["runs"][1]["temperature_c"][2] = json!(500.0);
    assert_eq!(
        pointers(&refused(&app, hot, "/v1/identify/thermal/triad").await),
        ["/runs/1/temperature_c/2"]
    );
    let mut words = drifting;
    words["runs"][0]["temperature_c"] = json!("warm");
    let p = refused(&app, words, "/v1/identify/thermal/triad").await;
    assert_eq!(pointers(&p), ["/runs/0/temperature_c"], "{p}");
}
