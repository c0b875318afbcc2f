//! Coefficients over temperature (issue 45), `POST /v1/identify/thermal`:
//! a tumble at five chamber set points with planted temperature models
//! (k0 quadratic, ki linear, kp constant) comes back with each set point
//! identified exactly as `POST /v1/identify` identifies its runs alone,
//! each polynomial the weighted least-squares fit (computed here, by the
//! normal equations) of the planted degree, and every refusal naming what
//! to add.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

/// The chamber's set points, °C, and the reference (their mean).
pub const CHAMBER: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];

/// The planted model at `t` °C: `(k0, ki, kp)`.
fn planted(t: f64) -> [f64; 3] {
    let dt = t - 20.0;
    [1e-3 + 2e-5 * dt + 3e-7 * dt * dt, -1.2 + 6e-5 * dt, 5e-3]
}

/// A deterministic deviate in (−1, 1) for `k`.
fn jitter(k: u64) -> f64 {
    let x = k.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(17) ^ 0x5851_f42d_4c95_7f2d;
    (x % 2_000_001) as f64 / 1_000_000.0 - 1.0
}

/// Eight runs at each of `set_points` (fused in four batches), two samples
/// a position, the run's temperature within ±0.02 K of its set point (a
/// chamber held steady), noise 1e-5.
pub fn body(set_points: &[f64]) -> Value {
    let angles = [0.0f64, 90.0, 180.0, 270.0];
    let mut runs = Vec::new();
    for (s, &t) in set_points.iter().enumerate() {
        for r in 0..8u64 {
            let k = (s as u64) * 100 + r * 10;
            let temperature = t + 0.02 * jitter(k);
            let [k0, ki, kp] = planted(temperature);
            let readings: Vec<Value> = angles
                .iter()
                .enumerate()
                .map(|(p, deg)| {
                    let th = deg.to_radians();
                    let u = k0 + ki * -th.sin() + kp * th.cos();
                    json!([
                        u + 1e-5 * jitter(k + p as u64 + 1),
                        u + 1e-5 * jitter(k + p as u64 + 5)
                    ])
                })
                .collect();
            runs.push(json!({"readings": readings, "temperature_c": temperature}));
        }
    }
    json!({"sensor_id": "MEMS-T", "unit": "V", "model": ["k0", "ki", "kp"], "mount": "pendulum",
           "positions": angles.iter().map(|a| json!({"angle_deg": a})).collect::<Vec<_>>(),
           "runs": runs, "batches": 4})
}

pub fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

/// Weighted least squares by the normal equations (Gaussian elimination):
/// `(a, (XᵀWX)⁻¹ diagonal)` of degree `d` about `tref`.
fn normal_equations(t: &[f64], c: &[f64], u: &[f64], tref: f64, d: usize) -> (Vec<f64>, Vec<f64>) {
    let n = d + 1;
    let x = |s: usize, k: usize| (t[s] - tref).powi(k as i32);
    // [XᵀWX | XᵀWc | I]
    let mut m: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            let mut row: Vec<f64> = (0..n)
                .map(|j| {
                    (0..t.len())
                        .map(|s| x(s, i) * x(s, j) / (u[s] * u[s]))
                        .sum()
                })
                .collect();
            row.push((0..t.len()).map(|s| x(s, i) * c[s] / (u[s] * u[s])).sum());
            row.extend((0..n).map(|j| f64::from(u8::from(i == j))));
            row
        })
        .collect();
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))
            .unwrap();
        m.swap(col, pivot);
        let p = m[col][col];
        m[col].iter_mut().for_each(|v| *v /= p);
        for r in 0..n {
            if r != col {
                let factor = m[r][col];
                let pivot_row = m[col].clone();
                m[r].iter_mut()
                    .zip(pivot_row)
                    .for_each(|(v, p)| *v -= factor * p);
            }
        }
    }
    (
        (0..n).map(|i| m[i][n]).collect(),
        (0..n).map(|i| m[i][n + 1 + i]).collect(),
    )
}

/// Checks the answered polynomial `p` (named `what`) against the weighted
/// fit of its degree to `c` ± `u` at `t` by the normal equations: each
/// `a_d`, its standard uncertainty with the covariance inflated by
/// `max(1, χ²/ν)`, and `χ²`.
pub(crate) fn is_the_weighted_fit(p: &Value, t: &[f64], c: &[f64], u: &[f64], what: &str) {
    let degree = p["degree"].as_u64().unwrap() as usize;
    let tref = f(&p["reference_c"]);
    let (a, var) = normal_equations(t, c, u, tref, degree);
    let chi2: f64 = (0..t.len())
        .map(|s| {
            let fit: f64 = (0..=degree)
                .map(|d| a[d] * (t[s] - tref).powi(d as i32))
                .sum();
            ((c[s] - fit) / u[s]).powi(2)
        })
        .sum();
    let inflation = (chi2 / (t.len() - 1 - degree) as f64).max(1.0);
    for d in 0..=degree {
        let su = (var[d] * inflation).sqrt();
        assert!(
            (f(&p["coefficients"][d]) - a[d]).abs() < 1e-6 * su,
            "{what} a_{d}"
        );
        assert!(
            (f(&p["std_uncertainties"][d]) / su - 1.0).abs() < 1e-6,
            "{what} u(a_{d})"
        );
    }
    assert!(
        (f(&p["chi2"]) - chi2).abs() < 1e-6 * chi2.max(1.0),
        "{what} χ²"
    );
}

#[tokio::test]
async fn five_set_points_give_each_coefficient_its_planted_degree() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    let res = app.post("/v1/identify/thermal", ADMIN, &b).await;
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{r}");
    assert_eq!(
        (r["selection"].as_str(), f(&r["tolerance_k"])),
        (Some("backward"), 0.5)
    );

    // Five set points of eight runs each, coolest first; each identified as
    // POST /v1/identify identifies its runs alone.
    let set_points = r["set_points"].as_array().unwrap();
    assert_eq!(set_points.len(), 5);
    for (s, sp) in set_points.iter().enumerate() {
        let runs: Vec<usize> = sp["runs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| j.as_u64().unwrap() as usize)
            .collect();
        assert_eq!(runs, (8 * s..8 * s + 8).collect::<Vec<_>>());
        assert!((f(&sp["temperature_c"]) - CHAMBER[s]).abs() < 0.02);
        let mut alone = b.clone();
        alone["runs"] = json!(
            runs.iter()
                .map(|&j| b["runs"][j].clone())
                .collect::<Vec<_>>()
        );
        let one: Value = app
            .post("/v1/identify", ADMIN, &alone)
            .await
            .json()
            .await
            .unwrap();
        assert_eq!(
            sp["coefficients"], one["fused"]["coefficients"],
            "set point {s}"
        );
        assert_eq!(
            sp["std_errors"], one["fused"]["std_errors"],
            "set point {s}"
        );
        assert_eq!(sp["batches"], 4);
    }

    // Each polynomial: the planted degree, T_ref the set points' mean to
    // 0.1 K, and the weighted fit the normal equations give.
    let t: Vec<f64> = set_points.iter().map(|s| f(&s["temperature_c"])).collect();
    for (term, degree) in [("k0", 2), ("ki", 1), ("kp", 0)] {
        let p = &r["coefficients"][term];
        assert_eq!(p["degree"], degree, "{term}: {p}");
        let tref = f(&p["reference_c"]);
        assert!((tref - (t.iter().sum::<f64>() / 5.0 * 10.0).round() / 10.0).abs() < 1e-12);
        let c: Vec<f64> = set_points
            .iter()
            .map(|s| f(&s["coefficients"][term]))
            .collect();
        let u: Vec<f64> = set_points
            .iter()
            .map(|s| f(&s["std_errors"][term]))
            .collect();
        is_the_weighted_fit(p, &t, &c, &u, term);
        assert_eq!(p["range_c"][0], set_points[0]["temperature_c"]);
        assert_eq!(p["range_c"][1], set_points[4]["temperature_c"]);
        // The planted model within the stated uncertainty at T_ref (a_0)
        // and, for the slopes, a_1.
        let want = planted(tref)[["k0", "ki", "kp"].iter().position(|x| *x == term).unwrap()];
        assert!(
            (f(&p["coefficients"][0]) - want).abs() < 4.0 * f(&p["std_uncertainties"][0]),
            "{term} at T_ref"
        );
    }
    assert!(
        (f(&r["coefficients"]["ki"]["coefficients"][1]) - 6e-5).abs()
            < 4.0 * f(&r["coefficients"]["ki"]["std_uncertainties"][1])
    );
}

#[tokio::test]
async fn a_fixed_degree_and_the_forward_rule_are_answered_as_asked() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    let r: Value = app
        .post(
            "/v1/identify/thermal?degree=1&tolerance_k=1&reference_c=25",
            ADMIN,
            &b,
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["selection"], "fixed");
    for term in ["k0", "ki", "kp"] {
        let p = &r["coefficients"][term];
        assert_eq!(
            (p["degree"].as_u64(), f(&p["reference_c"])),
            (Some(1), 25.0),
            "{term}"
        );
        assert_eq!(p["selection"], json!([]));
    }
    let r: Value = app
        .post("/v1/identify/thermal?selection=forward", ADMIN, &b)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["selection"], "forward");
    // The forward selection: each degree is the count of leading
    // significant tests, up to the first that is not.
    for term in ["k0", "ki", "kp"] {
        let p = &r["coefficients"][term];
        let tests = p["selection"].as_array().unwrap();
        let significant = tests.iter().take_while(|t| f(&t["p_value"]) < 0.01).count();
        assert_eq!(
            p["degree"].as_u64().unwrap() as usize,
            significant,
            "{term}: {p}"
        );
        assert!(significant == tests.len() || f(&tests[significant]["p_value"]) >= 0.01);
    }
}

#[tokio::test]
async fn what_cannot_make_a_sane_polynomial_is_refused_naming_what_to_add() {
    let app = TestApp::spawn(Sqlite).await;
    // A 4 K span: add a set point at or above 24 °C or at or below 16 °C.
    let p = problem(
        app.post("/v1/identify/thermal", ADMIN, &body(&[20.0, 22.0, 24.0]))
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    let detail = p["errors"][0]["detail"].as_str().unwrap();
    assert_eq!(p["errors"][0]["pointer"], "/runs");
    assert!(
        detail.contains("span")
            && detail.contains("at or below 14")
            && detail.contains("at or above 30"),
        "{detail}"
    );
    // One set point: one more needed.
    let p = problem(
        app.post("/v1/identify/thermal", ADMIN, &body(&[20.0]))
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    let detail = p["errors"][0]["detail"].as_str().unwrap();
    assert!(
        detail.contains("1 temperature set point(s)") && detail.contains("add 1 more"),
        "{detail}"
    );
    // Degree 3 on three set points: two more.
    let p = problem(
        app.post(
            "/v1/identify/thermal?degree=3",
            ADMIN,
            &body(&[-20.0, 20.0, 60.0]),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    let detail = p["errors"][0]["detail"].as_str().unwrap();
    assert!(
        detail.contains("add 2 more") && detail.contains("e.g. at"),
        "{detail}"
    );
    // A cubic through a cluster: condition number about 300, past the default
    // limit of 100; the widest gap is 21.8 to 35 °C.
    let crowded = body(&[20.0, 20.6, 21.2, 21.8, 35.0]);
    let res = app
        .post("/v1/identify/thermal?degree=3", ADMIN, &crowded)
        .await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    let detail = p["errors"][0]["detail"].as_str().unwrap();
    assert!(
        detail.contains("condition number 30")
            && detail.contains("past the limit 100")
            && detail.contains("e.g. at 28.4"),
        "{detail}"
    );
    // No temperatures at all.
    let mut none = body(&CHAMBER);
    for r in none["runs"].as_array_mut().unwrap() {
        r.as_object_mut().unwrap().remove("temperature_c");
    }
    let p = problem(
        app.post("/v1/identify/thermal", ADMIN, &none).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(p["errors"][0]["pointer"], "/runs/0/temperature_c");
    // A sensor type is not applied yet: refused, not ignored.
    let mut typed = body(&CHAMBER);
    typed["sensor_type"] = json!("NAV");
    let p = problem(
        app.post("/v1/identify/thermal", ADMIN, &typed).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(p["errors"][0]["pointer"], "/sensor_type");
    // Parameters out of range or unknown: 400 naming them.
    for (query, name) in [
        ("degree=4", "degree"),
        ("tolerance_k=-1", "tolerance_k"),
        ("min_span_k=NaN", "min_span_k"),
        ("selection=sideways", "selection"),
        ("order=2", "order"),
    ] {
        let p = problem(
            app.post(
                &format!("/v1/identify/thermal?{query}"),
                ADMIN,
                &body(&CHAMBER),
            )
            .await,
            StatusCode::BAD_REQUEST,
        )
        .await;
        assert!(
            p["detail"].as_str().unwrap().contains(&format!("`{name}`")),
            "{query}: {p}"
        );
    }
}

/// A chamber that drifts during a run (item 1): a run's temperature given
/// per position enters the fit at the positions' mean — the model equals
/// the one of the same runs each given that mean, computed here — and is
/// kept as a single axis's run temperature too; a run that drifted more
/// than the set points' tolerance is refused, naming it.
#[tokio::test]
async fn a_drifting_chamber_gives_a_temperature_per_position() {
    let app = TestApp::spawn(Sqlite).await;
    let mut drifting = body(&CHAMBER);
    let mut means = drifting.clone();
    let runs = drifting["runs"].as_array_mut().unwrap();
    for (j, run) in runs.iter_mut().enumerate() {
        let t = f(&run["temperature_c"]);
        let each = [t - 0.1, t, t + 0.1, t + 0.3];
        run["temperature_c"] = json!(each);
        means["runs"][j]["temperature_c"] = json!(each.iter().sum::<f64>() / 4.0);
    }
    let fit = |b: Value| {
        let app = &app;
        async move {
            let res = app.post("/v1/identify/thermal", ADMIN, &b).await;
            assert_eq!(res.status(), StatusCode::OK);
            res.json::<Value>().await.unwrap()
        }
    };
    let (per_position, by_mean) = (fit(drifting.clone()).await, fit(means.clone()).await);
    assert_eq!(per_position, by_mean);
    assert!((f(&per_position["set_points"][0]["temperature_c"]) + 19.925).abs() < 0.03);

    // As a single axis's calibration: the run's temperature is the mean.
    let mut one = drifting.clone();
    one["runs"] = json!(drifting["runs"].as_array().unwrap()[..8]);
    let stored = app.submit(ADMIN, &one).await;
    assert_eq!(
        stored["temperatures_c"],
        json!(
            means["runs"].as_array().unwrap()[..8]
                .iter()
                .map(|r| r["temperature_c"].clone())
                .collect::<Vec<_>>()
        )
    );

    // 0.6 K across one run's positions, more than 0.5 K: refused.
    let t = f(&means["runs"][3]["temperature_c"]);
    drifting["runs"][3]["temperature_c"] = json!([t, t + 0.2, t + 0.4, t + 0.6]);
    let p = problem(
        app.post("/v1/identify/thermal", ADMIN, &drifting).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/runs/3/temperature_c"], "{p}");
    assert!(p.to_string().contains("drifted 0.600 K"), "{p}");
    // Allowed by a wider tolerance.
    let res = app
        .post("/v1/identify/thermal?tolerance_k=1", ADMIN, &drifting)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
}
