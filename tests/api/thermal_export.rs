//! A triad's temperature model as files (issue 45 item 5),
//! `POST /v1/identify/thermal/triad?export=…`: PX4's and ArduPilot's
//! thermal parameters evaluate, under each autopilot's own formula
//! (written out here from its sources, not taken from accelcal), to the
//! model's `b(T)`; both refuse with 409 `not-carried` a model whose scale
//! factors move over the range beyond their expanded uncertainty, naming
//! them with the change a dense scan of the model finds; `json` and `c`
//! carry every polynomial.

use std::collections::HashMap;

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::Sqlite;
use accelcal_testkit::*;

use crate::thermal_triad::{CHAMBER, body_with, f};

/// The temperature model `POST /v1/identify/thermal/triad` fits to `b`.
async fn model_of(app: &TestApp, b: &Value) -> Value {
    let res = app.post("/v1/identify/thermal/triad", ADMIN, b).await;
    assert_eq!(res.status(), StatusCode::OK);
    res.json().await.unwrap()
}

/// The model of `b` and its file in `export`.
async fn model_and_file(app: &TestApp, b: &Value, export: &str) -> (Value, String) {
    let model = model_of(app, b).await;
    let res = app
        .post(
            &format!("/v1/identify/thermal/triad?export={export}"),
            ADMIN,
            b,
        )
        .await;
    let status = res.status();
    let file = res.text().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{file}");
    (model, file)
}

/// The polynomial at `pointer` of `model` at `t`, from its coefficients.
fn eval(model: &Value, pointer: &str, t: f64) -> f64 {
    let p = model.pointer(pointer).unwrap();
    let x = t - f(&p["reference_c"]);
    p["coefficients"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(d, a)| f(a) * x.powi(d as i32))
        .sum()
}

/// The problem `POST /v1/identify/thermal/triad?export={format}` answers
/// `b` with, of `status`.
async fn refused(app: &TestApp, format: &str, b: &Value, status: StatusCode) -> Value {
    let path = format!("/v1/identify/thermal/triad?export={format}");
    problem(app.post(&path, ADMIN, b).await, status).await
}

/// The temperatures checked: across the range and past both ends.
const CHECKED: [f64; 10] = [-40.0, -20.0, -7.5, 0.0, 13.7, 20.0, 33.3, 45.0, 59.9, 80.0];

/// PX4's thermal parameters evaluate, under PX4's own formula
/// (`calc_thermal_offsets_3D`: `X0 + X1 dT + X2 dT² + X3 dT³`, `dT` the
/// temperature clamped to `TMIN…TMAX` less `TREF`), to the model's `b(T)`
/// at every temperature of the range, and to its ends outside it; `S(T)`,
/// constant here, is said not carried.
#[tokio::test]
async fn px4_parameters_evaluate_to_the_models_bias() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body_with(&CHAMBER, 0.0);
    let (model, file) = model_and_file(&app, &b, "px4&tolerance_k=0.5").await;
    let params: HashMap<String, (f64, String)> = file
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
    let px4_offset = |i: usize, t: f64| -> f64 {
        let dt = t.clamp(t_min, t_max) - p("TC_A0_TREF");
        (0..4)
            .map(|d| p(&format!("TC_A0_X{d}_{i}")) * dt.powi(d))
            .sum()
    };
    for t in CHECKED {
        for i in 0..3 {
            let want = eval(&model, &format!("/b/{i}"), t.clamp(t_min, t_max));
            let got = px4_offset(i, t);
            assert!(
                (want - got).abs() < 1e-9,
                "b_{i}({t}): {want} against {got}"
            );
        }
    }
    assert!(file.contains("NOT CARRIED: S(T)"), "{file}");
    for term in ["S_xx", "S_xy", "S_zz"] {
        assert!(file.contains(&format!("#   {term} ")), "{term}: {file}");
    }
    assert!(file.contains("CAL_ACC0_xOFF to 0"), "{file}");
}

/// ArduPilot's parameters evaluate, under ArduPilot's own correction
/// (`TCal::correct_sensor` then the offsets: `INS_ACCOFFS + p(T) −
/// p(CALTEMP)`, `p(T) = (ACC1 x + ACC2 x² + ACC3 x³) · 1e-6`, `x` the
/// temperature clamped to `TMIN…TMAX` less 35 °C), to the model's `b(T)`.
#[tokio::test]
async fn ardupilot_parameters_evaluate_to_the_models_bias() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body_with(&CHAMBER, 0.0);
    let res = app
        .post("/v1/identify/thermal/triad?export=ardupilot", ADMIN, &b)
        .await;
    assert_eq!(
        res.headers()["content-disposition"].to_str().unwrap(),
        "attachment; filename=\"accelcal-ardupilot-thermal.param\""
    );
    let (model, file) = model_and_file(&app, &b, "ardupilot").await;
    let params: HashMap<String, f64> = file
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let (name, value) = l.split_once(',').unwrap_or_else(|| panic!("{l}"));
            (name.to_owned(), value.parse().unwrap())
        })
        .collect();
    assert_eq!(params.len(), 3 + 9 + 1 + 3, "{file}");
    let p = |name: &str| params[name];
    assert_eq!(p("INS_TCAL1_ENABLE"), 1.0);
    let (t_min, t_max) = (p("INS_TCAL1_TMIN"), p("INS_TCAL1_TMAX"));
    assert!((t_min - f(&model["b"][0]["range_c"][0])).abs() < 1e-6);
    assert!((t_max - f(&model["b"][0]["range_c"][1])).abs() < 1e-6);
    // The offsets are calibrated at T_ref.
    assert_eq!(p("INS_ACC1_CALTEMP"), 20.0);
    let poly = |axis: &str, t: f64| -> f64 {
        let x = t.clamp(t_min, t_max) - 35.0;
        (1..=3)
            .map(|k| p(&format!("INS_TCAL1_ACC{k}_{axis}")) * x.powi(k))
            .sum::<f64>()
            * 1e-6
    };
    for t in CHECKED {
        for (i, axis) in ["X", "Y", "Z"].iter().enumerate() {
            let offset = p(&format!("INS_ACCOFFS_{axis}")) + poly(axis, t)
                - poly(axis, p("INS_ACC1_CALTEMP"));
            let want = eval(&model, &format!("/b/{i}"), t.clamp(t_min, t_max));
            assert!(
                (want - offset).abs() < 1e-9,
                "b_{i}({t}): {want} against {offset}"
            );
        }
    }
    // b_z, planted constant, has no temperature term.
    if model["b"][2]["degree"] == 0 {
        assert_eq!(p("INS_TCAL1_ACC1_Z"), 0.0);
    }
    assert!(file.contains("NOT CARRIED: S(T)"), "{file}");
    assert!(
        file.contains("TEMP_REFERENCE") || file.contains("35"),
        "{file}"
    );
}

/// `S_zz changes by 7.85e-2 (U 1.23e-3) at 60 °C` → (term, E, U, T).
fn named(detail: &str) -> Vec<(String, f64, f64, f64)> {
    detail
        .split("S_")
        .skip(1)
        .filter_map(|part| {
            let term = format!("S_{}", part.get(..2)?);
            let rest = part
                .strip_prefix(&term[2..])?
                .strip_prefix(" changes by ")?;
            let (e, rest) = rest.split_once(" (U ")?;
            let (u, rest) = rest.split_once(") at ")?;
            let (t, _) = rest.split_once(" °C")?;
            Some((term, e.parse().ok()?, u.parse().ok()?, t.parse().ok()?))
        })
        .collect()
}

/// A scale factor planted to move with the temperature cannot go to PX4
/// or ArduPilot: 409 `not-carried` names each moving element with its
/// largest change over the range and the expanded uncertainty (k = 2,
/// `√(vᵀ C v)` with `v = (0, x, x², x³)`) there, as a scan of the model's
/// own polynomials over 4 001 temperatures finds them; `json` and `c`
/// carry the whole model.
#[tokio::test]
async fn formats_without_a_thermal_scale_factor_refuse_one_that_moves() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body_with(&CHAMBER, 1.0);
    let model = model_of(&app, &b).await;
    for format in ["px4", "ardupilot"] {
        let p = refused(&app, format, &b, StatusCode::CONFLICT).await;
        assert_eq!(p["type"], "urn:accelcal:problem:not-carried", "{p}");
        let detail = p["detail"].as_str().unwrap();
        let terms = named(detail);
        let names: Vec<&str> = terms.iter().map(|t| t.0.as_str()).collect();
        for planted in ["S_xx", "S_yy", "S_zz"] {
            assert!(names.contains(&planted), "{planted}: {detail}");
        }
        for (term, e, u, at) in &terms {
            let (m, n) = (axis(&term[2..3]), axis(&term[3..4]));
            let poly = &model["S"][m][n];
            let (want_e, want_u, want_at) = scan(poly);
            assert!(
                (e - want_e).abs() <= 0.01 * want_e,
                "{term}: {e} against {want_e}"
            );
            assert!(
                (u - want_u).abs() <= 0.01 * want_u,
                "{term}: {u} against {want_u}"
            );
            assert!(
                (at - want_at).abs() < 0.02,
                "{term}: {at} against {want_at}"
            );
            assert!(e > u, "{term}");
        }
        // The worst first, by E / U.
        let ratios: Vec<f64> = terms.iter().map(|t| t.1 / t.2).collect();
        assert!(ratios.windows(2).all(|w| w[0] >= w[1] * 0.99), "{detail}");
    }
    // json: the model itself; c: every polynomial to 13 digits.
    let (_, json_file) = model_and_file(&app, &b, "json").await;
    let exported: Value = serde_json::from_str(&json_file).unwrap();
    assert_eq!(exported, model);
    let (_, c) = model_and_file(&app, &b, "c").await;
    assert!(c.contains("#ifndef ACCELCAL_TRIAD_THERMAL_H"), "{c}");
    assert!(
        c.contains("static const double ACCELCAL_T_REF = 20.000000;"),
        "{c}"
    );
    let numbers = |name: &str| -> Vec<f64> {
        let start = c.find(&format!("static const double {name}[")).unwrap();
        let body = &c[start..];
        let body = &body[body.find('=').unwrap() + 1..body.find("};").unwrap()];
        body.split(|ch: char| ch == ',' || ch == '{' || ch == '}' || ch.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect()
    };
    c_evaluates_to_the_model(&c, &model);
    let b_poly = numbers("ACCELCAL_B_POLY");
    let s_poly = numbers("ACCELCAL_S_POLY");
    assert_eq!((b_poly.len(), s_poly.len()), (12, 36));
    let same = |got: f64, p: &Value, d: usize| {
        let want = p["coefficients"].get(d).map_or(0.0, f);
        assert!(
            (got - want).abs() <= 1e-12 * want.abs(),
            "{got} against {want}"
        );
    };
    for m in 0..3 {
        for d in 0..4 {
            same(b_poly[4 * m + d], &model["b"][m], d);
            for n in 0..3 {
                same(s_poly[12 * m + 4 * n + d], &model["S"][m][n], d);
            }
        }
    }
}

/// A C program that evaluates every polynomial of the header at 33.3 °C
/// by Horner's rule, as firmware would.
const EVAL_C: &str = r#"#include <stdio.h>
#include "accelcal_thermal_triad.h"
static double at(const double p[4], double t) {
    double x = t - ACCELCAL_T_REF;
    return ((p[3] * x + p[2]) * x + p[1]) * x + p[0];
}
int main(void) {
    double t = 33.3;
    int m, n;
    if (t < ACCELCAL_T_MIN || t > ACCELCAL_T_MAX) return 2;
    printf("%s %s", ACCELCAL_UNIT, ACCELCAL_SOURCE[0] ? "ok" : "none");
    for (m = 0; m < 3; m++) printf(" %.15e", at(ACCELCAL_B_POLY[m], t));
    for (m = 0; m < 3; m++)
        for (n = 0; n < 3; n++) printf(" %.15e", at(ACCELCAL_S_POLY[m][n], t));
    return 0;
}
"#;

/// The C header compiles clean and, evaluated by [`EVAL_C`], gives the
/// model's `b` and `S` at 33.3 °C.
fn c_evaluates_to_the_model(header: &str, model: &Value) {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("accelcal_thermal_triad.h"), header).unwrap();
    std::fs::write(dir.path().join("main.c"), EVAL_C).unwrap();
    let exe = dir.path().join("main");
    let out = Command::new("cc")
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic", "-I"])
        .arg(dir.path())
        .arg(dir.path().join("main.c"))
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("a C compiler (cc) on PATH");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new(&exe).output().unwrap();
    assert!(out.status.success(), "33.3 °C outside the header's range");
    let text = String::from_utf8(out.stdout).unwrap();
    let words: Vec<&str> = text.split(' ').collect();
    assert_eq!(&words[..2], ["m/s2", "ok"], "{text}");
    let mut want = Vec::new();
    for m in 0..3 {
        want.push(eval(model, &format!("/b/{m}"), 33.3));
    }
    for m in 0..3 {
        for n in 0..3 {
            want.push(eval(model, &format!("/S/{m}/{n}"), 33.3));
        }
    }
    for (got, want) in words[2..].iter().zip(&want) {
        let got: f64 = got.parse().unwrap();
        assert!(
            (got - want).abs() <= 1e-11 * want.abs().max(1e-3),
            "{got} against {want}"
        );
    }
    assert_eq!(words.len(), 2 + 12, "{text}");
}

fn axis(a: &str) -> usize {
    ["x", "y", "z"].iter().position(|x| *x == a).unwrap()
}

/// The largest `|Δ(T)|` of `poly` over 4 001 temperatures of its range,
/// the expanded uncertainty `2 √(vᵀ C v)` there, and where.
fn scan(poly: &Value) -> (f64, f64, f64) {
    let (lo, hi) = (f(&poly["range_c"][0]), f(&poly["range_c"][1]));
    let a: Vec<f64> = poly["coefficients"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    let c: Vec<Vec<f64>> = poly["covariance"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_array().unwrap().iter().map(f).collect())
        .collect();
    let tref = f(&poly["reference_c"]);
    (0..=4000)
        .map(|i| {
            let t = lo + (hi - lo) * i as f64 / 4000.0;
            let v: Vec<f64> = (0..a.len())
                .map(|d| {
                    if d == 0 {
                        0.0
                    } else {
                        (t - tref).powi(d as i32)
                    }
                })
                .collect();
            let e: f64 = (0..a.len()).map(|d| a[d] * v[d]).sum();
            let var: f64 = (0..a.len())
                .flat_map(|i| (0..a.len()).map(move |j| (i, j)))
                .map(|(i, j)| v[i] * c[i][j] * v[j])
                .sum();
            (e.abs(), 2.0 * var.sqrt(), t)
        })
        .fold(
            (0.0, 0.0, lo),
            |best, x| if x.0 > best.0 { x } else { best },
        )
}

/// Only the four formats; PX4 and ArduPilot need an acceleration unit.
#[tokio::test]
async fn unknown_formats_and_units_are_refused() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body_with(&CHAMBER, 0.0);
    let p = refused(&app, "mavlink", &b, StatusCode::BAD_REQUEST).await;
    assert_eq!(p["parameter"], "export", "{p}");
    // An unknown parameter is told every one there is, `export` too.
    let p = problem(
        app.post("/v1/identify/thermal/triad?colour=red", ADMIN, &b)
            .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "colour", "{p}");
    let detail = p["detail"].as_str().unwrap();
    assert!(
        detail.contains("`tolerance_k`") && detail.ends_with("or `export`"),
        "{p}"
    );
    let mut volts = b.clone();
    volts["unit"] = json!("V");
    for format in ["px4", "ardupilot"] {
        let p = refused(&app, format, &volts, StatusCode::UNPROCESSABLE_ENTITY).await;
        assert!(p["detail"].as_str().unwrap().contains("m/s²"), "{p}");
    }
}

/// The example triad (examples/thermal-triad.py) comes back with its
/// planted bias polynomials within four standard uncertainties, and its
/// scale factors' 40 ppm/K are what PX4 refuses, naming each.
#[tokio::test]
async fn the_example_triad_recovers_its_bias_and_cannot_go_to_px4() {
    let app = TestApp::spawn(Sqlite).await;
    let b: Value = serde_json::from_str(include_str!("../../examples/thermal-triad.json")).unwrap();
    let model = model_of(&app, &b).await;
    let planted = [
        [0.183, 1.6e-3, 1.1e-5],
        [-0.127, -0.9e-3, 0.0],
        [0.342, 2.4e-3, -0.8e-5],
    ];
    for (m, want) in planted.iter().enumerate() {
        let p = &model["b"][m];
        for (d, w) in want.iter().enumerate() {
            let a = p["coefficients"].get(d).map_or(0.0, f);
            let u = p["std_uncertainties"].get(d).map_or(0.0, f);
            assert!(
                (a - w).abs() <= 4.0 * u.max(1e-12),
                "b_{m} a_{d}: {a} ± {u} against {w}"
            );
        }
    }
    let p = refused(&app, "px4", &b, StatusCode::CONFLICT).await;
    let named: Vec<String> = named(p["detail"].as_str().unwrap())
        .into_iter()
        .map(|t| t.0)
        .collect();
    for term in ["S_xx", "S_yy", "S_zz"] {
        assert!(named.iter().any(|n| n == term), "{term}: {p}");
    }
}
