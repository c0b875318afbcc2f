//! A single axis's temperature model stored as a calibration (issue 45
//! items 1 and 3), `POST /v1/calibrations/thermal`, on both engines: the
//! model stored is the one `POST /v1/identify/thermal` fits; the
//! coefficients at a temperature and compensation there are the stored
//! polynomials evaluated — computed here from the model's own JSON, `Σ a_d
//! x^d` with `√(vᵀ C v)`, and the single-axis model inverted by hand —
//! through a restart (read back from the database); outside the range
//! they are refused unless extrapolation is allowed, and then say by how
//! far; a calibration without a model refuses a temperature; reprocessing
//! fits the same model again; the trail verifies.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

use crate::thermal::{CHAMBER, body, f};

/// `(c(t), u(c(t)))` of the polynomial `p` (a stored model's JSON).
pub(crate) fn evaluated(p: &Value, t: f64) -> (f64, f64) {
    let x = t - f(&p["reference_c"]);
    let a: Vec<f64> = p["coefficients"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    let c: Vec<Vec<f64>> = p["covariance"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_array().unwrap().iter().map(f).collect())
        .collect();
    let v: Vec<f64> = (0..a.len()).map(|d| x.powi(d as i32)).collect();
    let value = (0..a.len()).map(|d| a[d] * v[d]).sum();
    let var: f64 = (0..a.len())
        .flat_map(|i| (0..a.len()).map(move |j| (i, j)))
        .map(|(i, j)| v[i] * c[i][j] * v[j])
        .sum();
    (value, var.sqrt())
}

/// The result document calibration `id` has once reprocessed (its
/// replacement's, or its own when the reprocessing changed nothing).
pub(crate) async fn reprocessed(app: &TestApp, id: &str) -> Value {
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/reprocess"),
            ADMIN,
            &json!({}),
        )
        .await;
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::OK, "{r}");
    let id = r["replacement_id"].as_str().unwrap_or(id);
    app.get_json(&format!("/v1/calibrations/{id}"), ADMIN).await
}

fn near(got: f64, want: f64, what: &str) {
    assert!(
        (got - want).abs() <= 1e-12 * want.abs().max(1e-9),
        "{what}: {got} against {want}"
    );
}

#[rstest]
#[tokio::test]
async fn a_stored_model_serves_its_coefficients_and_compensation_at_a_temperature(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let mut app = TestApp::spawn(engine).await;
    let b = body(&CHAMBER);
    let fitted: Value = app
        .post("/v1/identify/thermal", ADMIN, &b)
        .await
        .json()
        .await
        .unwrap();
    let res = app.post("/v1/calibrations/thermal", ADMIN, &b).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let stored: Value = res.json().await.unwrap();
    crate::conforms_to("StoredThermal", &stored);
    assert_eq!(stored["kind"], "thermal");
    // The model stored is the one identify fits, and its coefficients are
    // the model at T_ref.
    assert_eq!(stored["thermal"], fitted);
    assert_eq!(stored["reference_c"], 20.0);
    for term in ["k0", "ki", "kp"] {
        let p = &fitted["coefficients"][term];
        assert_eq!(stored["coefficients"][term], p["coefficients"][0], "{term}");
        assert_eq!(
            stored["std_errors"][term], p["std_uncertainties"][0],
            "{term}"
        );
    }
    let id = stored["id"].as_str().unwrap().to_owned();

    // Restarted: everything below is read back from the database.
    app.stop().await;
    let db = app.take_database().unwrap();
    let mut app = TestApp::spawn_on(&db.url).await;
    let coefficients = "/v1/sensors/MEMS-T/coefficients";
    let at_ref = app.get_json(coefficients, ADMIN).await;
    assert_eq!(at_ref["coefficients"], stored["coefficients"]);
    assert_eq!(at_ref["temperature"]["temperature_c"], 20.0);
    assert_eq!(
        at_ref["temperature"]["range_c"],
        fitted["coefficients"]["k0"]["range_c"]
    );

    let model = &fitted["coefficients"];
    // The range is the set points' mean temperatures: -19.997 to 60.002.
    for t in [-19.99, 0.5, 33.0, 60.0] {
        let r = app
            .get_json(&format!("{coefficients}?temperature_c={t}"), ADMIN)
            .await;
        assert_eq!(r["calibration_id"], json!(id));
        assert_eq!(r["temperature"]["temperature_c"], t);
        assert_eq!(r["temperature"]["extrapolated"], false);
        for term in ["k0", "ki", "kp"] {
            let (c, u) = evaluated(&model[term], t);
            near(f(&r["coefficients"][term]), c, &format!("{term}({t})"));
            near(f(&r["std_errors"][term]), u, &format!("u({term}({t}))"));
        }
    }

    // Compensation: u = k0 + ki a_i + kp a_p inverted with the model at
    // each output's temperature (one for all, or one each).
    let invert = |u: f64, t: f64, a_p: f64| {
        let c = |term: &str| evaluated(&model[term], t).0;
        (u - c("k0") - c("kp") * a_p) / c("ki")
    };
    let compensate = "/v1/sensors/MEMS-T/compensate";
    let r: Value = app
        .post(
            compensate,
            ADMIN,
            &json!({"outputs": [0.5, -1.1], "a_p": [0.0, 0.2], "temperature_c": 33.0}),
        )
        .await
        .json()
        .await
        .unwrap();
    near(f(&r["a_i"][0]), invert(0.5, 33.0, 0.0), "a_i at 33");
    near(f(&r["a_i"][1]), invert(-1.1, 33.0, 0.2), "a_i at 33");
    assert_eq!(r["temperature"]["temperature_c"], 33.0);
    let r: Value = app
        .post(
            compensate,
            ADMIN,
            &json!({"outputs": [0.5, 0.5], "temperature_c": [-10.0, 55.0],
                    "calibration_id": id}),
        )
        .await
        .json()
        .await
        .unwrap();
    near(f(&r["a_i"][0]), invert(0.5, -10.0, 0.0), "a_i at -10");
    near(f(&r["a_i"][1]), invert(0.5, 55.0, 0.0), "a_i at 55");
    assert!(
        f(&r["a_i"][0]) != f(&r["a_i"][1]),
        "the temperature matters"
    );
    assert_eq!(r["temperature"]["temperature_c"], json!([-10.0, 55.0]));

    // Outside the range: refused, naming where, unless allowed; then said.
    let t_max = f(&fitted["coefficients"]["k0"]["range_c"][1]);
    let p = problem(
        app.get(&format!("{coefficients}?temperature_c=70"), ADMIN)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(p["parameter"], "temperature_c", "{p}");
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("allow_extrapolation"),
        "{p}"
    );
    let r = app
        .get_json(
            &format!("{coefficients}?temperature_c=70&allow_extrapolation=true"),
            ADMIN,
        )
        .await;
    assert_eq!(r["temperature"]["extrapolated"], true);
    near(
        f(&r["temperature"]["extrapolated_k"]),
        70.0 - t_max,
        "extrapolated_k",
    );
    near(
        f(&r["coefficients"]["k0"]),
        evaluated(&model["k0"], 70.0).0,
        "k0(70)",
    );
    let p = problem(
        app.post(
            compensate,
            ADMIN,
            &json!({"outputs": [0.5, 0.5], "temperature_c": [20.0, -40.0]}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/temperature_c/1"], "{p}");
    let r: Value = app
        .post(
            compensate,
            ADMIN,
            &json!({"outputs": [0.5], "temperature_c": -40.0, "allow_extrapolation": true}),
        )
        .await
        .json()
        .await
        .unwrap();
    near(f(&r["a_i"][0]), invert(0.5, -40.0, 0.0), "a_i at -40");
    assert_eq!(r["temperature"]["extrapolated"], true);
    // A model needs the temperature; one per output or one for all.
    for (bad, pointer) in [
        (json!({"outputs": [0.5]}), "/temperature_c"),
        (
            json!({"outputs": [0.5, 0.4], "temperature_c": [20.0]}),
            "/temperature_c",
        ),
        (
            json!({"outputs": [0.5], "temperature_c": 900}),
            "/temperature_c",
        ),
        (
            json!({"outputs": [0.5], "temperature_c": "warm"}),
            "/temperature_c",
        ),
    ] {
        let p = problem(
            app.post(compensate, ADMIN, &bad).await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(pointers(&p), [pointer], "{bad}: {p}");
    }

    // A calibration without a model refuses a temperature.
    let plain = app
        .submit(ADMIN, &submission("PLAIN-1", "2026-01-01T00:00:00Z", 4))
        .await;
    assert!(plain["id"].is_string());
    let p = problem(
        app.get("/v1/sensors/PLAIN-1/coefficients?temperature_c=20", ADMIN)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(
        p["detail"]
            .as_str()
            .unwrap()
            .contains("no temperature model"),
        "{p}"
    );
    let p = problem(
        app.post(
            "/v1/sensors/PLAIN-1/compensate",
            ADMIN,
            &json!({"outputs": [0.5], "temperature_c": 20}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/temperature_c"], "{p}");

    // Not approved, its certificate is a draft (tests/api/thermal_certificate.rs
    // reads an issued one).
    let res = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    assert!(res.text().await.unwrap().contains("data-term=\"k0_a0\""));

    // Its page shows the model and links its certificate; the sensor's
    // page lists it.
    let (session, _) = crate::ui::sign_in(&app, ADMIN).await;
    let res = crate::ui::page(&app, &format!("/ui/calibrations/{id}"), &session).await;
    assert_eq!(res.status(), StatusCode::OK);
    let html = res.text().await.unwrap();
    for part in [
        "Temperature model of MEMS-T",
        "thermal-polynomials",
        "thermal-set-points",
    ] {
        assert!(html.contains(part), "{part}");
    }
    assert!(html.contains("id=\"dcc-link\""), "the DCC's link");
    let res = crate::ui::page(&app, "/ui/sensors/MEMS-T", &session).await;
    assert_eq!(res.status(), StatusCode::OK);
    assert!(res.text().await.unwrap().contains(&id));

    // Reprocessing fits the same model again, with the parameters it was
    // fitted with.
    let again = reprocessed(&app, &id).await;
    assert_eq!(again["thermal"]["coefficients"], fitted["coefficients"]);

    // And the trail vouches for the rows, the model's included.
    app.stop().await;
    crate::audit::verifies(app.database.clone()).await;
    drop(db);
}

/// What a stored model cannot use is refused, naming it;
/// a degree or tolerance out of range is a 400 naming the parameter.
#[tokio::test]
async fn what_a_stored_model_cannot_use_is_refused() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    // A sensor type that does not exist; a standard that does not.
    let mut typed = b.clone();
    typed["sensor_type"] = json!("NO-SUCH-TYPE");
    let p = problem(
        app.post("/v1/calibrations/thermal", ADMIN, &typed).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/sensor_type"], "{p}");
    let mut with_standards = b.clone();
    with_standards["standards"] = json!({"stand": "DH-1"});
    let p = problem(
        app.post("/v1/calibrations/thermal", ADMIN, &with_standards)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/standards/stand"], "{p}");
    let p = problem(
        app.post("/v1/calibrations/thermal?degree=7", ADMIN, &b)
            .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "degree", "{p}");
    // Too small a span: nothing stored.
    let p = problem(
        app.post("/v1/calibrations/thermal", ADMIN, &body(&[20.0, 25.0]))
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(
        p["errors"][0]["detail"]
            .as_str()
            .unwrap()
            .contains("less than the 10 K"),
        "{p}"
    );
    let res = app.get("/v1/sensors/MEMS-T", ADMIN).await;
    assert_eq!(res.status(), StatusCode::NOT_FOUND);
}

/// One `Idempotency-Key` is one request: the same key and bytes sent as a
/// single axis and then as a temperature model, or fitted otherwise, are
/// refused as a reused key, not answered with what the first stored; the
/// same request again is answered with it.
#[tokio::test]
async fn a_key_names_the_kind_and_the_fit_it_was_sent_with() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    let send = |path: &'static str| {
        app.client
            .post(app.url(path))
            .bearer_auth(ADMIN)
            .header("idempotency-key", "chamber-1")
            .json(&b)
            .send()
    };
    let first = send("/v1/calibrations/thermal").await.unwrap();
    assert_eq!(first.status(), StatusCode::CREATED);
    let first: Value = first.json().await.unwrap();
    let again = send("/v1/calibrations/thermal").await.unwrap();
    assert_eq!(again.headers()["idempotent-replayed"], "true");
    assert_eq!(again.json::<Value>().await.unwrap()["id"], first["id"]);
    for other in ["/v1/calibrations", "/v1/calibrations/thermal?degree=1"] {
        let p = problem(send(other).await.unwrap(), StatusCode::UNPROCESSABLE_ENTITY).await;
        assert_eq!(
            p["type"], "urn:accelcal:problem:idempotency-key-reused",
            "{other}: {p}"
        );
    }
}

/// The example chamber run (examples/thermal-chamber.py) is stored with
/// its planted polynomials within four standard uncertainties, and its
/// coefficients at 33 °C are the planted model's there within four.
#[tokio::test]
async fn the_example_chamber_run_recovers_its_planted_model() {
    let app = TestApp::spawn(Sqlite).await;
    let b: Value =
        serde_json::from_str(include_str!("../../examples/thermal-chamber.json")).unwrap();
    let res = app.post("/v1/calibrations/thermal", ADMIN, &b).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let stored: Value = res.json().await.unwrap();
    let planted: [(&str, &[f64]); 3] = [
        ("k0", &[0.0021, 3.5e-5, 2.2e-7]),
        ("ki", &[1.2148, -1.2148 * 1.2e-4]),
        ("kp", &[0.0032]),
    ];
    for (term, want) in planted {
        let p = &stored["thermal"]["coefficients"][term];
        assert_eq!(
            p["degree"].as_u64().unwrap() as usize,
            want.len() - 1,
            "{term}: {p}"
        );
        for (d, w) in want.iter().enumerate() {
            let (a, u) = (f(&p["coefficients"][d]), f(&p["std_uncertainties"][d]));
            assert!(
                (a - w).abs() <= 4.0 * u,
                "{term} a_{d}: {a} ± {u} against {w}"
            );
        }
    }
    let r = app
        .get_json("/v1/sensors/MEMS-TC-7/coefficients?temperature_c=33", ADMIN)
        .await;
    let dt = 13.0;
    for (term, want) in [
        ("k0", 0.0021 + 3.5e-5 * dt + 2.2e-7 * dt * dt),
        ("ki", 1.2148 * (1.0 - 1.2e-4 * dt)),
        ("kp", 0.0032),
    ] {
        let (c, u) = (f(&r["coefficients"][term]), f(&r["std_errors"][term]));
        assert!(
            (c - want).abs() <= 4.0 * u,
            "{term}(33): {c} ± {u} against {want}"
        );
    }
}

/// The guarded rule (ILAC-G8), written out here: pass inside the limits by
/// `U`, fail outside them by `U`, conditional between.
pub(crate) fn guarded(value: f64, u: f64, min: f64, max: f64) -> &'static str {
    if value - u >= min && value + u <= max {
        "pass"
    } else if value + u < min || value - u > max {
        "fail"
    } else {
        "conditional"
    }
}

/// A typed sensor's model is judged at every set point and across its
/// range, each coefficient by its worst: k0, planted to rise past its
/// upper limit above about 50 °C though well inside it at T_ref, fails
/// where a scan of the stored polynomial (4 001 temperatures, U = 2 u)
/// and the set points (U = 2 se) say it does; ki passes; the sensor's
/// coefficients are then not usable, and its due date is the type's.
#[rstest]
#[tokio::test]
async fn a_typed_sensors_model_is_judged_over_its_range(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let (k0_max, ki_min, ki_max) = (2.0e-3, -1.21, -1.19);
    let res = app
        .put(
            "/v1/sensor-types/CHAMBER",
            ADMIN,
            &json!({"unit": "V", "decision_rule": "guarded", "coverage_factor": 2.0,
                    "interval_days": 180,
                    "limits": {"k0": {"max": k0_max}, "ki": {"min": ki_min, "max": ki_max}}}),
        )
        .await;
    assert!(res.status().is_success(), "{}", res.text().await.unwrap());
    let mut b = body(&CHAMBER);
    b["sensor_type"] = json!("CHAMBER");
    // Outputs in another unit than the type's limits, and a limit on a
    // term the model lacks, are refused where they are.
    let mut in_ma = b.clone();
    in_ma["unit"] = json!("mA");
    let p = problem(
        app.post("/v1/calibrations/thermal", ADMIN, &in_ma).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/unit"], "{p}");
    let res = app
        .put(
            "/v1/sensor-types/SECOND-ORDER",
            ADMIN,
            &json!({"unit": "V", "decision_rule": "simple", "interval_days": 180,
                    "limits": {"kii": {"max": 1e-3}}}),
        )
        .await;
    assert!(res.status().is_success());
    let mut kii = b.clone();
    kii["sensor_type"] = json!("SECOND-ORDER");
    kii["sensor_id"] = json!("MEMS-K2");
    let p = problem(
        app.post("/v1/calibrations/thermal", ADMIN, &kii).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/model"], "{p}");
    let res = app.post("/v1/calibrations/thermal", ADMIN, &b).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let stored: Value = res.json().await.unwrap();
    let d = &stored["decision"];
    assert_eq!(d["rule"], "guarded");
    assert_eq!(stored["sensor_type"], "CHAMBER");

    let model = &stored["thermal"];
    for (term, min, max) in [("k0", f64::NEG_INFINITY, k0_max), ("ki", ki_min, ki_max)] {
        let p = &model["coefficients"][term];
        let j = &d["terms"][term];
        // Each set point, by its own fused value and 2 se.
        let mut verdicts = Vec::new();
        for (s, sp) in model["set_points"].as_array().unwrap().iter().enumerate() {
            let (v, se) = (f(&sp["coefficients"][term]), f(&sp["std_errors"][term]));
            let want = guarded(v, 2.0 * se, min, max);
            assert_eq!(j["set_points"][s]["verdict"], want, "{term} set point {s}");
            verdicts.push(want);
        }
        // Across the range, by the polynomial and 2 u(T).
        let (lo, hi) = (f(&p["range_c"][0]), f(&p["range_c"][1]));
        let mut worst = ("pass", lo);
        for i in 0..=4000 {
            let t = lo + (hi - lo) * f64::from(i) / 4000.0;
            let (v, u) = evaluated(p, t);
            let verdict = guarded(v, 2.0 * u, min, max);
            let rank = |v: &str| ["pass", "conditional", "fail"].iter().position(|x| *x == v);
            if rank(verdict) > rank(worst.0) {
                worst = (verdict, t);
            }
        }
        assert_eq!(j["range"]["verdict"], worst.0, "{term}: {j}");
        verdicts.push(worst.0);
        let overall = ["fail", "conditional", "pass"]
            .into_iter()
            .find(|v| verdicts.contains(v))
            .unwrap();
        assert_eq!(j["worst"]["verdict"], overall, "{term}: {j}");
    }
    assert_eq!(d["terms"]["k0"]["worst"]["verdict"], "fail");
    assert!(f(&d["terms"]["k0"]["worst"]["temperature_c"]) > 40.0);
    assert_eq!(d["terms"]["ki"]["worst"]["verdict"], "pass");
    assert_eq!(d["verdict"], "fail");
    // At T_ref k0 is well inside: only the range says it fails.
    assert!(f(&stored["coefficients"]["k0"]) + 2.0 * f(&stored["std_errors"]["k0"]) < k0_max);

    let c = app.get_json("/v1/sensors/MEMS-T/coefficients", ADMIN).await;
    assert_eq!(c["verdict"], "fail");
    assert_eq!(c["usable"], false);
    use accelcal::domain::timestamp::Timestamp;
    let at = |v: &Value| Timestamp::parse(v.as_str().unwrap()).unwrap();
    assert_eq!(
        at(&c["due_at"]),
        at(&stored["performed_at"]).plus_seconds(180 * 86_400)
    );
    assert_eq!(c["due_at"], stored["due_at"]);
    // The page states the decision, the worst first.
    let (session, _) = crate::ui::sign_in(&app, ADMIN).await;
    let id = stored["id"].as_str().unwrap();
    let html = crate::ui::page(&app, &format!("/ui/calibrations/{id}"), &session)
        .await
        .text()
        .await
        .unwrap();
    assert!(html.contains("thermal-decision"), "{html}");
    assert!(html.contains("badge fail"), "the verdict beside the title");
    let p = problem(
        app.get(
            "/v1/sensors/MEMS-T/coefficients?require=usable&temperature_c=20",
            ADMIN,
        )
        .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert_eq!(p["type"], "urn:accelcal:problem:not-usable", "{p}");
}
