//! A triad's temperature model from static positions in unknown
//! orientations (issue 45 item 1, triads), `POST
//! /v1/identify/thermal/triad` with `static_positions` and each position's
//! temperature: each set point is fitted from the gravity magnitude exactly
//! as `POST /v1/identify/triad` fits its positions alone, every measured
//! element's polynomial is the weighted fit (the normal equations, here)
//! and recovers the planted model, the elements zero by the frame
//! convention are exactly zero and not judged; stored, it compensates at a
//! temperature to the planted gravity vector; every refusal names what to
//! fix.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

use crate::thermal_triad::{f, fits_its_set_points, jitter, refused};

pub(crate) const CHAMBER: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];

/// The planted triad at `t` °C in the frame a fit from the gravity
/// magnitude uses (the sensor's x axis and xy-plane: `S` lower-triangular):
/// `b_x`, `b_y` and the scale factors linear in temperature, the rest
/// constant.
pub(crate) fn planted(t: f64) -> ([f64; 3], [[f64; 3]; 3]) {
    let dt = t - 20.0;
    let b = [0.05 + 1e-3 * dt, -0.03 + 5e-4 * dt, 0.02];
    let s = [
        [9.81 * (1.0 + 1e-4 * dt), 0.0, 0.0],
        [0.0015, 9.79 * (1.0 - 5e-5 * dt), 0.0],
        [-0.002, 0.001, 9.83 * (1.0 + 2e-4 * dt)],
    ];
    (b, s)
}

/// Fourteen directions: the six faces and the eight corners of a cube.
fn directions() -> Vec<[f64; 3]> {
    let mut d = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let c = 1.0 / 3f64.sqrt();
    for x in [-c, c] {
        for y in [-c, c] {
            for z in [-c, c] {
                d.push([x, y, z]);
            }
        }
    }
    d
}

/// The outputs `b + S g` of the planted triad at `t`.
fn outputs(t: f64, g: [f64; 3]) -> [f64; 3] {
    let (b, s) = planted(t);
    std::array::from_fn(|m| b[m] + (0..3).map(|c| s[m][c] * g[c]).sum::<f64>())
}

/// Each direction held still at each of `set_points` (within ±0.02 K),
/// three samples each, noise 2e-4 m/s².
pub(crate) fn body(set_points: &[f64]) -> Value {
    let (mut positions, mut temperatures) = (Vec::new(), Vec::new());
    for (sp, &t) in set_points.iter().enumerate() {
        for (p, g) in directions().into_iter().enumerate() {
            let k = (sp as u64) * 10_000 + (p as u64) * 100;
            let temperature = t + 0.02 * jitter(k);
            let u = outputs(temperature, g);
            let samples: Vec<Vec<f64>> = (0..3u64)
                .map(|n| {
                    (0..3)
                        .map(|m| u[m] + 2e-4 * jitter(k + 3 * n + m as u64 + 1))
                        .collect()
                })
                .collect();
            positions.push(json!(samples));
            temperatures.push(temperature);
        }
    }
    json!({"sensor_id": "IMU-S", "unit": "m/s2", "static_positions": positions,
           "static_temperatures_c": temperatures})
}

#[tokio::test]
async fn static_positions_at_five_set_points_give_the_planted_model() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    let res = app.post("/v1/identify/thermal/triad", ADMIN, &b).await;
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{r}");
    crate::conforms_to("TriadThermalModel", &r);
    assert_eq!(r["method"], "gravity_magnitude");

    // Each set point fitted as POST /v1/identify/triad fits its positions
    // alone (without their temperatures).
    let set_points = r["set_points"].as_array().unwrap();
    assert_eq!(set_points.len(), 5);
    let n = directions().len();
    for (s, sp) in set_points.iter().enumerate() {
        let positions: Vec<usize> = sp["runs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| j.as_u64().unwrap() as usize)
            .collect();
        assert_eq!(positions, (n * s..n * s + n).collect::<Vec<_>>());
        let alone = json!({"unit": "m/s2", "static_positions":
            positions.iter().map(|&j| b["static_positions"][j].clone()).collect::<Vec<_>>()});
        let res = app.post("/v1/identify/triad", ADMIN, &alone).await;
        assert_eq!(res.status(), StatusCode::OK);
        let one: Value = res.json().await.unwrap();
        assert_eq!(one["method"], "gravity_magnitude");
        for key in ["b", "b_std_errors", "S", "S_std_errors"] {
            assert_eq!(sp[key], one[key], "set point {s}: {key}");
        }
        for m in 0..3 {
            assert_eq!(
                sp["axes_dof"][m]["k0"],
                f64::from(u32::try_from(n - 9).unwrap())
            );
        }
    }

    // Every measured element: the weighted fit at its degree; the planted
    // value at T_ref within four standard uncertainties. Above the
    // diagonal of S: exactly zero, not fitted.
    let (b_ref, s_ref) = planted(20.0);
    for m in 0..3 {
        fits_its_set_points(&r, m, None, b_ref[m]);
        for k in 0..3 {
            if k > m {
                let p = &r["S"][m][k];
                assert_eq!(p["coefficients"], json!([0.0]), "S[{m}][{k}]");
                assert_eq!(p["std_uncertainties"], json!([0.0]), "S[{m}][{k}]");
            } else {
                fits_its_set_points(&r, m, Some(k), s_ref[m][k]);
            }
        }
    }
    let slope = |pointer: &str| {
        let p = r.pointer(pointer).unwrap();
        (f(&p["coefficients"][1]), f(&p["std_uncertainties"][1]))
    };
    let (a1, u1) = slope("/b/0");
    assert!((a1 - 1e-3).abs() < 4.0 * u1, "{a1} ± {u1}");
    let (a1, u1) = slope("/S/2/2");
    assert!((a1 - 9.83 * 2e-4).abs() < 4.0 * u1, "{a1} ± {u1}");

    // Stored for a typed triad: judged on the measured elements only; it
    // compensates the planted outputs at 33 °C to the gravity vector.
    let res = app
        .put(
            "/v1/sensor-types/IMU-S",
            ADMIN,
            &json!({"unit": "m/s2", "decision_rule": "simple", "interval_days": 365,
                    "limits": {"k0": {"min": -0.5, "max": 0.5}, "ki": {"min": 9.6, "max": 10.0},
                               "kp": {"min": -0.1, "max": 0.1}}}),
        )
        .await;
    assert!(res.status().is_success());
    let mut typed = b.clone();
    typed["sensor_type"] = json!("IMU-S");
    let res = app
        .post("/v1/calibrations/thermal/triad", ADMIN, &typed)
        .await;
    let status = res.status();
    let stored: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{stored}");
    assert_eq!(stored["thermal"], r);
    assert_eq!(stored["elements"]["method"], "gravity_magnitude");
    let judged: Vec<&str> = stored["decision"]["elements"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    // kp is S_xy, S_yz (zero by convention) and S_zx.
    assert_eq!(
        judged,
        ["S_xx", "S_yy", "S_zx", "S_zz", "b_x", "b_y", "b_z"],
        "{}",
        stored["decision"]
    );
    assert_eq!(stored["decision"]["verdict"], "pass");
    let g = [0.6, -0.48, 0.64];
    let u = outputs(33.0, g);
    let c: Value = app
        .post(
            "/v1/sensors/IMU-S/compensate",
            ADMIN,
            &json!({"outputs": [u], "temperature_c": 33.0}),
        )
        .await
        .json()
        .await
        .unwrap();
    for k in 0..3 {
        assert!(
            (f(&c["g"][0][k]) - g[k]).abs() < 1e-4,
            "g[{k}] at 33 °C: {c}"
        );
    }
    let id = stored["id"].as_str().unwrap();
    let res = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    assert!(
        res.text()
            .await
            .unwrap()
            .contains("by the frame convention")
    );
}

#[tokio::test]
async fn static_positions_refusals_name_what_to_fix() {
    let app = TestApp::spawn(Sqlite).await;
    let thermal = "/v1/identify/thermal/triad";
    let b = body(&CHAMBER);
    // A set point of nine positions: no standard errors to weight with.
    let mut nine = b.clone();
    let first: Vec<Value> = nine["static_positions"].as_array().unwrap()[..9].to_vec();
    let rest: Vec<Value> = nine["static_positions"].as_array().unwrap()[14..].to_vec();
    nine["static_positions"] = json!([first, rest].concat());
    let ts = nine["static_temperatures_c"].as_array().unwrap().clone();
    nine["static_temperatures_c"] = json!([&ts[..9], &ts[14..]].concat());
    let p = refused(&app, nine, thermal).await;
    assert_eq!(pointers(&p), ["/static_positions/0"], "{p}");
    assert!(p["detail"].as_str().unwrap().contains("at least 10"), "{p}");
    // A count other than the positions', an implausible one.
    let mut short = b.clone();
    short["static_temperatures_c"].as_array_mut().unwrap().pop();
    assert_eq!(
        pointers(&refused(&app, short, thermal).await),
        ["/static_temperatures_c"]
    );
    let mut hot = b.clone();
    hot["static_temperatures_c"][3] = json!(500.0);
    assert_eq!(
        pointers(&refused(&app, hot, thermal).await),
        ["/static_temperatures_c/3"]
    );
    // None given to the model; given to a triad at one temperature.
    let mut none = b.clone();
    none.as_object_mut()
        .unwrap()
        .remove("static_temperatures_c");
    let p = refused(&app, none, thermal).await;
    assert_eq!(pointers(&p), ["/static_temperatures_c"], "{p}");
    // Given to a triad at one temperature: refused at the reading farthest
    // from their mean.
    let odd = farthest(b["static_temperatures_c"].as_array().unwrap());
    let p = refused(&app, b.clone(), "/v1/identify/triad").await;
    assert_eq!(
        pointers(&p),
        [format!("/static_temperatures_c/{odd}")],
        "{p}"
    );
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("/v1/identify/thermal/triad")
    );
    // With known orientations each run gives its own.
    let mut known = crate::thermal_triad::body(&CHAMBER);
    known["static_temperatures_c"] = json!([20.0]);
    let p = refused(&app, known, thermal).await;
    assert!(
        pointers(&p).contains(&"/static_temperatures_c".to_owned()),
        "{p}"
    );
}

/// The CSV layouts with a `temperature_c` column: the static positions'
/// and the known orientations' (a drifting run one per position) give the
/// models their JSON gives, to the last bit. Sent here as the CSV text a
/// station writes of the same body, `{}` formatting every number so that
/// it reads back the same.
#[tokio::test]
async fn csv_with_a_temperature_column_gives_the_json_model() {
    let app = TestApp::spawn(Sqlite).await;
    let fit = |ct: &'static str, body: Vec<u8>| {
        let app = &app;
        async move {
            let res = app
                .client
                .post(app.url("/v1/identify/thermal/triad"))
                .bearer_auth(ADMIN)
                .header("content-type", ct)
                .body(body)
                .send()
                .await
                .unwrap();
            let status = res.status();
            let r: Value = res.json().await.unwrap();
            assert_eq!(status, StatusCode::OK, "{r}");
            r
        }
    };
    let json_fit = |b: &Value| fit("application/json", serde_json::to_vec(b).unwrap());

    let b = body(&CHAMBER);
    let mut csv = String::from("# unit: m/s2\nposition,u_x,u_y,u_z,temperature_c\n");
    for (p, samples) in b["static_positions"].as_array().unwrap().iter().enumerate() {
        let t = f(&b["static_temperatures_c"][p]);
        for u in samples.as_array().unwrap() {
            let [x, y, z] = [0, 1, 2].map(|k| f(&u[k]));
            csv.push_str(&format!("P{p},{x},{y},{z},{t}\n"));
        }
    }
    let mut want = json_fit(&b).await;
    want["sensor_id"] = Value::Null;
    assert_eq!(fit("text/csv", csv.into_bytes()).await, want);

    let mut known = crate::thermal_triad::body(&CHAMBER);
    let drift = [-0.1, -0.06, -0.02, 0.03, 0.07, 0.12];
    let faces: [[f64; 3]; 6] = [
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let mut csv =
        String::from("# unit: m/s2\n# batches: 2\nrun,g_x,g_y,g_z,u_x,u_y,u_z,temperature_c\n");
    for (j, run) in known["runs"].as_array_mut().unwrap().iter_mut().enumerate() {
        let t = f(&run["temperature_c"]);
        let each: Vec<f64> = drift.iter().map(|d| t + d).collect();
        for (p, samples) in run["samples"].as_array().unwrap().iter().enumerate() {
            let [gx, gy, gz] = faces[p];
            for u in samples.as_array().unwrap() {
                let [x, y, z] = [0, 1, 2].map(|k| f(&u[k]));
                csv.push_str(&format!("{j},{gx},{gy},{gz},{x},{y},{z},{}\n", each[p]));
            }
        }
        run["temperature_c"] = json!(each);
    }
    known["orientations"] = json!(faces);
    let mut want = json_fit(&known).await;
    want["sensor_id"] = Value::Null;
    assert_eq!(fit("text/csv", csv.into_bytes()).await, want);
}

/// A continuous recording through the five set points at 25 Hz: each of
/// the fourteen directions held 4 s (the first 5 s, the detector's still
/// start), 1.5 s of motion between, every sample with its temperature
/// (the set point's, within ±0.03 K).
fn recording() -> Value {
    recording_of(&CHAMBER)
}

/// [`recording`] through `set_points`.
pub(crate) fn recording_of(set_points: &[f64]) -> Value {
    let rate = 25.0;
    let (mut samples, mut temperatures) = (Vec::new(), Vec::new());
    let dirs = directions();
    let mut k = 0u64;
    for (sp, &t_sp) in set_points.iter().enumerate() {
        for (p, g) in dirs.iter().enumerate() {
            let t = t_sp + 0.02 * jitter(7_000 + 100 * sp as u64 + p as u64);
            let hold = if sp == 0 && p == 0 { 5.0 } else { 4.0 };
            let u = outputs(t, *g);
            for _ in 0..(hold * rate) as usize {
                k += 1;
                samples.push(
                    (0..3)
                        .map(|m| u[m] + 2e-4 * jitter(3 * k + m as u64))
                        .collect::<Vec<f64>>(),
                );
                temperatures.push(t + 0.01 * jitter(5 * k + 1));
            }
            // Moving on to the next direction (or the next set point's first).
            let next = outputs(t, dirs[(p + 1) % dirs.len()]);
            let n = (1.5 * rate) as usize;
            for i in 0..n {
                let s = (i + 1) as f64 / (n + 1) as f64;
                let wave = 3.0 * (std::f64::consts::PI * s).sin();
                samples.push(
                    (0..3)
                        .map(|m| u[m] * (1.0 - s) + next[m] * s + wave)
                        .collect(),
                );
                temperatures.push(t);
            }
        }
    }
    json!({"sensor_id": "IMU-R", "unit": "m/s2",
           "recording": {"rate_hz": rate, "samples": samples, "temperature_c": temperatures}})
}

/// A recording with each sample's temperature: every static interval a
/// position at its samples' mean temperature, fitted as static positions
/// are; the planted model recovered; refusals name the recording's
/// temperatures.
#[tokio::test]
async fn a_recording_with_its_temperatures_gives_the_planted_model() {
    let app = TestApp::spawn(Sqlite).await;
    let rec = recording();
    let res = app.post("/v1/identify/thermal/triad", ADMIN, &rec).await;
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(
        status,
        StatusCode::OK,
        "{}",
        r.to_string().get(..600).unwrap_or_default()
    );
    assert_eq!(r["method"], "gravity_magnitude");
    let set_points = r["set_points"].as_array().unwrap();
    assert_eq!(set_points.len(), 5);
    for (s, sp) in set_points.iter().enumerate() {
        assert_eq!(sp["runs"].as_array().unwrap().len(), 14, "set point {s}");
        assert!((f(&sp["temperature_c"]) - CHAMBER[s]).abs() < 0.03);
    }
    let (b_ref, s_ref) = planted(20.0);
    for (pointer, want) in [
        ("/b/0", b_ref[0]),
        ("/b/1", b_ref[1]),
        ("/S/0/0", s_ref[0][0]),
        ("/S/2/0", s_ref[2][0]),
        ("/S/2/2", s_ref[2][2]),
    ] {
        let p = r.pointer(pointer).unwrap();
        assert!(
            (f(&p["coefficients"][0]) - want).abs() < 4.0 * f(&p["std_uncertainties"][0]),
            "{pointer} at T_ref: {} against {want}",
            p["coefficients"][0]
        );
    }
    let p = r.pointer("/b/0").unwrap();
    let (a1, u1) = (f(&p["coefficients"][1]), f(&p["std_uncertainties"][1]));
    assert!((a1 - 1e-3).abs() < 4.0 * u1, "{a1} ± {u1}");
    assert_eq!(r["S"][0][1]["coefficients"], json!([0.0]));

    let thermal = "/v1/identify/thermal/triad";
    let mut none = rec.clone();
    none["recording"]
        .as_object_mut()
        .unwrap()
        .remove("temperature_c");
    let p = refused(&app, none, thermal).await;
    assert_eq!(pointers(&p), ["/recording/temperature_c"], "{p}");
    let mut short = rec.clone();
    short["recording"]["temperature_c"]
        .as_array_mut()
        .unwrap()
        .pop();
    let p = refused(&app, short, thermal).await;
    assert_eq!(pointers(&p), ["/recording/temperature_c"], "{p}");
    // The chamber warming by 1 K during the third hold.
    let mut drifting = rec.clone();
    let ts = drifting["recording"]["temperature_c"]
        .as_array_mut()
        .unwrap();
    for (i, t) in ts.iter_mut().enumerate().skip(300).take(60) {
        *t = json!(f(t) + (i - 300) as f64 / 60.0);
    }
    let p = refused(&app, drifting, thermal).await;
    assert_eq!(pointers(&p), ["/recording/temperature_c"], "{p}");
    assert!(p["detail"].as_str().unwrap().contains("drifted"), "{p}");
    let odd = farthest(rec["recording"]["temperature_c"].as_array().unwrap());
    let p = refused(&app, rec, "/v1/identify/triad").await;
    assert_eq!(
        pointers(&p),
        [format!("/recording/temperature_c/{odd}")],
        "{p}"
    );
}

/// The index of the reading farthest from the readings' mean.
fn farthest(readings: &[Value]) -> usize {
    let t: Vec<f64> = readings.iter().map(f).collect();
    let mean = t.iter().sum::<f64>() / t.len() as f64;
    (0..t.len())
        .max_by(|&a, &b| (t[a] - mean).abs().total_cmp(&(t[b] - mean).abs()))
        .unwrap()
}
