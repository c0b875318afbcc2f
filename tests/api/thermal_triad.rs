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
const CHAMBER: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];

/// The planted triad at `t` °C: `b` (m/s², x quadratic, y linear, z
/// constant) and `S` (m/s² per g: the scale factors linear, the rest
/// constant).
fn planted(t: f64) -> ([f64; 3], [[f64; 3]; 3]) {
    let dt = t - 20.0;
    let b = [0.05 + 1e-3 * dt + 2e-5 * dt * dt, -0.03 + 5e-4 * dt, 0.02];
    let s = [
        [9.81 * (1.0 + 1e-4 * dt), 0.002, -0.001],
        [0.0015, 9.79 * (1.0 - 5e-5 * dt), 0.003],
        [-0.002, 0.001, 9.83 * (1.0 + 2e-4 * dt)],
    ];
    (b, s)
}

/// A deterministic deviate in (−1, 1) for `k`.
fn jitter(k: u64) -> f64 {
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
fn body(set_points: &[f64]) -> Value {
    let mut runs = Vec::new();
    for (sp, &t) in set_points.iter().enumerate() {
        for r in 0..10u64 {
            let k = (sp as u64) * 1000 + r * 100;
            let temperature = t + 0.02 * jitter(k);
            let (b, s) = planted(temperature);
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

fn f(v: &Value) -> f64 {
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
    let t: Vec<f64> = set_points.iter().map(|s| f(&s["temperature_c"])).collect();
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
        let of = |sp: &Value, key: &str| match n {
            None => f(&sp[key][m]),
            Some(n) => f(&sp[key][m][n]),
        };
        let (values, errors) = match n {
            None => ("b", "b_std_errors"),
            Some(_) => ("S", "S_std_errors"),
        };
        let c: Vec<f64> = set_points.iter().map(|sp| of(sp, values)).collect();
        let u: Vec<f64> = set_points.iter().map(|sp| of(sp, errors)).collect();
        is_the_weighted_fit(p, &t, &c, &u, &pointer);
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
        assert!(
            (f(&p["coefficients"][0]) - at_tref).abs() < 4.0 * f(&p["std_uncertainties"][0]),
            "{pointer} at T_ref: {} against {at_tref}",
            p["coefficients"][0]
        );
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
    let refused = |body: Value, path: &'static str| {
        let app = &app;
        async move {
            let res = app.post(path, ADMIN, &body).await;
            problem(res, StatusCode::UNPROCESSABLE_ENTITY).await
        }
    };
    let thermal = "/v1/identify/thermal/triad";
    let pointer = |p: &Value| p["errors"][0]["pointer"].as_str().unwrap().to_owned();

    // One run without its temperature.
    let mut b = body(&CHAMBER);
    b["runs"][3]
        .as_object_mut()
        .unwrap()
        .remove("temperature_c");
    let p = refused(b, thermal).await;
    assert_eq!(pointer(&p), "/runs/3/temperature_c", "{p}");
    // A temperature no instrument reads.
    let mut b = body(&CHAMBER);
    b["runs"][0]["temperature_c"] = json!(300.0);
    let p = refused(b, thermal).await;
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
    let p = refused(b, thermal).await;
    assert_eq!(pointer(&p), "/runs/0/temperature_c", "{p}");
    // One set point: one more to add; a 4 K span: where to add one.
    let p = refused(body(&[20.0]), thermal).await;
    assert_eq!(pointer(&p), "/runs", "{p}");
    let detail = p["detail"].as_str().unwrap();
    assert!(detail.contains("add 1 more"), "{p}");
    let p = refused(body(&[20.0, 22.0, 24.0]), thermal).await;
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("add a set point at or below 14 °C or at or above 29.99 °C"),
        "{p}"
    );
    // Unknown orientations, second-order terms: not modelled.
    let p = refused(
        json!({"unit": "m/s2", "static_positions": vec![vec![[0.0, 0.0, 9.8]]; 9]}),
        thermal,
    )
    .await;
    assert_eq!(pointer(&p), "/orientations", "{p}");
    let mut b = body(&CHAMBER);
    b["second_order"] = json!(true);
    assert_eq!(pointer(&refused(b, thermal).await), "/second_order");
    // Runs at several temperatures sent to the plain triad calibration:
    // pointed here rather than the temperatures ignored.
    let p = refused(body(&CHAMBER), "/v1/identify/triad").await;
    assert_eq!(pointer(&p), "/runs/0/temperature_c", "{p}");
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

/// PX4's thermal parameters evaluate, under PX4's own formula
/// (`calc_thermal_offsets_3D`: `X0 + X1 dT + X2 dT² + X3 dT³`, `dT` the
/// temperature clamped to `TMIN…TMAX` less `TREF`), to the model's `b(T)`
/// at every temperature of the range, and to its ends outside it; `S(T)`
/// is said not carried.
#[tokio::test]
async fn px4_parameters_evaluate_to_the_models_bias() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    let model: Value = app
        .post("/v1/identify/thermal/triad", ADMIN, &b)
        .await
        .json()
        .await
        .unwrap();
    let res = app
        .post(
            "/v1/identify/thermal/triad?export=px4&tolerance_k=0.5",
            ADMIN,
            &b,
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(
        res.headers()["content-type"].to_str().unwrap(),
        "text/plain; charset=utf-8"
    );
    let file = res.text().await.unwrap();
    let params: std::collections::HashMap<String, (f64, String)> = file
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let f: Vec<&str> = l.split('\t').collect();
            assert_eq!((f.len(), f[0], f[1]), (5, "1", "1"), "{l}");
            (f[2].to_owned(), (f[3].parse().unwrap(), f[4].to_owned()))
        })
        .collect();
    assert_eq!(params["TC_A_ENABLE"], (1.0, "6".to_owned()));
    let p = |name: &str| {
        let (v, t) = &params[name];
        assert_eq!(t, "9", "{name}");
        *v
    };
    assert_eq!(p("TC_A0_TREF"), 20.0);
    let (t_min, t_max) = (p("TC_A0_TMIN"), p("TC_A0_TMAX"));
    assert!((t_min - f(&model["b"][0]["range_c"][0])).abs() < 1e-6);
    assert!((t_max - f(&model["b"][0]["range_c"][1])).abs() < 1e-6);
    // The model's b_i(T) from its own coefficients, and PX4's offset.
    let model_b = |i: usize, t: f64| -> f64 {
        let poly = &model["b"][i];
        let dt = t - f(&poly["reference_c"]);
        poly["coefficients"]
            .as_array()
            .unwrap()
            .iter()
            .enumerate()
            .map(|(d, a)| f(a) * dt.powi(d as i32))
            .sum()
    };
    let px4_offset = |i: usize, t: f64| -> f64 {
        let dt = t.clamp(t_min, t_max) - p("TC_A0_TREF");
        (0..4)
            .map(|d| p(&format!("TC_A0_X{d}_{i}")) * dt.powi(d))
            .sum()
    };
    for t in [-20.0f64, -7.5, 0.0, 13.7, 20.0, 33.3, 45.0, 59.9] {
        let t = t.clamp(t_min, t_max);
        for i in 0..3 {
            let (want, got) = (model_b(i, t), px4_offset(i, t));
            assert!(
                (want - got).abs() < 1e-9,
                "b_{i}({t}): {want} against {got}"
            );
        }
    }
    // Outside the range PX4 holds the end's value, as the model's range asks.
    assert!((px4_offset(0, 80.0) - model_b(0, t_max)).abs() < 1e-9);
    assert!((px4_offset(0, -40.0) - model_b(0, t_min)).abs() < 1e-9);
    assert!(file.contains("NOT CARRIED: S_xx(T)"), "{file}");
    assert!(file.contains("CAL_ACC0_xOFF to 0"), "{file}");
    // Only px4 is a format here; outputs in no acceleration unit cannot be.
    let p = problem(
        app.post("/v1/identify/thermal/triad?export=c", ADMIN, &b)
            .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "export", "{p}");
    let mut volts = b.clone();
    volts["unit"] = json!("V");
    let p = problem(
        app.post("/v1/identify/thermal/triad?export=px4", ADMIN, &volts)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("m/s²"), "{p}");
}
