//! The metrology over HTTP: sensor types, decisions, uncertainty, as found,
//! due dates and status, stability, temperature and quality flags — each
//! value checked against a computation written here from the definitions.

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);

async fn put(app: &TestApp, path: &str, token: &str, body: &Value) -> reqwest::Response {
    app.client
        .put(app.url(path))
        .bearer_auth(token)
        .json(body)
        .send()
        .await
        .unwrap()
}

fn nav_type() -> Value {
    json!({
        "label": "Navigation grade",
        "unit": "mA",
        "limits": {"k0": {"min": -1e-3, "max": 1e-3}, "kp": {"min": -6.2e-3, "max": 6.2e-3}},
        "decision_rule": "guarded",
        "coverage_factor": 2,
        "interval_days": 180
    })
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[rstest]
#[tokio::test]
async fn sensor_types_are_written_by_admins_and_checked(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let res = put(&app, "/v1/sensor-types/NAV", ADMIN, &nav_type()).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let t: Value = res.json().await.unwrap();
    assert_eq!(
        (t["type_id"].as_str(), t["interval_days"].as_u64()),
        (Some("NAV"), Some(180))
    );
    assert_eq!(
        put(&app, "/v1/sensor-types/NAV", ADMIN, &nav_type())
            .await
            .status(),
        StatusCode::OK
    );
    let reader = app.token("reader", None).await;
    problem(
        put(&app, "/v1/sensor-types/X", &reader, &nav_type()).await,
        StatusCode::FORBIDDEN,
    )
    .await;
    let list: Value = app
        .get("/v1/sensor-types", &reader)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(list["items"][0]["type_id"], "NAV");
    problem(
        app.get("/v1/sensor-types/NONE", &reader).await,
        StatusCode::NOT_FOUND,
    )
    .await;
    for (body, pointer) in [
        (
            json!({"unit": "mA", "limits": {"k0": {"min": 1, "max": -1}}, "decision_rule": "simple"}),
            "/limits/k0",
        ),
        (
            json!({"unit": "mA", "limits": {"k0": {"max": 1}}, "decision_rule": "simple", "interval_days": -5}),
            "/interval_days",
        ),
        (
            json!({"unit": "mA", "limits": {"k9": {"min": 1}}, "decision_rule": "simple"}),
            "/limits/k9",
        ),
        (
            json!({"unit": "mA", "limits": {"k0": {"max": 1}}, "decision_rule": "strict"}),
            "/decision_rule",
        ),
    ] {
        let p = problem(
            put(&app, "/v1/sensor-types/BAD", ADMIN, &body).await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert!(pointers(&p).contains(&pointer.to_owned()), "{p}");
    }
}

/// The paper's submission on a typed sensor with a stand: the budget's
/// indexing and gravity parts follow the four-position closed form
/// (indexing(k0) = σ·√(ki² + kp²)/(2√2), indexing(ki) = σ·|kp|/√2,
/// indexing(kp) = σ·|ki|/√2; gravity = u·|k| on ki and kp), the guarded
/// decision follows ILAC-G8, and the due date is 180 days on.
#[rstest]
#[tokio::test]
async fn a_typed_calibration_carries_its_budget_decision_and_due_date(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    put(&app, "/v1/sensor-types/NAV", ADMIN, &nav_type()).await;
    let mut body = paper();
    body["unit"] = json!("mA");
    body["sensor_type"] = json!("NAV");
    body["stand"] = json!({"id": "DH-1", "angle_std_arcsec": 4.0, "gravity_rel_std": 2e-5});
    let r = app.submit(ADMIN, &body).await;
    let k = &r["fused"]["coefficients"];
    let se = &r["fused"]["std_errors"];
    let (ki, kp) = (f(&k["ki"]), f(&k["kp"]));
    let (sigma, u) = (4.0 * ARCSEC, 2e-5);
    let b = &r["uncertainty"]["terms"];
    let want = [
        (
            "k0",
            sigma * (ki * ki + kp * kp).sqrt() / (2.0 * 2f64.sqrt()),
            0.0,
        ),
        ("ki", sigma * kp.abs() / 2f64.sqrt(), u * ki.abs()),
        ("kp", sigma * ki.abs() / 2f64.sqrt(), u * kp.abs()),
    ];
    for (t, indexing, gravity) in want {
        close(&b[t]["indexing"], indexing, 1e-12 * indexing.abs() + 1e-20);
        close(&b[t]["gravity"], gravity, 1e-12 * gravity.abs() + 1e-18);
        assert_eq!(b[t]["statistical"], se[t]);
        let combined = (f(&se[t]).powi(2) + indexing.powi(2) + gravity.powi(2)).sqrt();
        close(&b[t]["combined"], combined, 1e-12 * combined);
        close(&b[t]["expanded"], 2.0 * combined, 1e-12 * combined);
    }
    assert_eq!(r["uncertainty"]["coverage_factor"], 2.0);
    assert_eq!(
        r["stand"],
        json!({"id": "DH-1", "angle_std_arcsec": 4.0, "gravity_rel_std": 2e-5})
    );
    assert_eq!(r["sensor_type"], "NAV");
    // ILAC-G8 guarded: k0 = −6.8e-4 ± U well inside ±1e-3 → pass; kp =
    // 6.2738e-3 is above the 6.2e-3 limit but within it + U → conditional.
    let d = &r["decision"];
    assert_eq!(d["rule"], "guarded");
    let verdict = |t: &str| {
        let (x, uu) = (f(&k[t]), f(&b[t]["expanded"]));
        let (lo, hi) = (
            f(&nav_type()["limits"][t]["min"]),
            f(&nav_type()["limits"][t]["max"]),
        );
        if lo + uu <= x && x <= hi - uu {
            "pass"
        } else if x < lo - uu || x > hi + uu {
            "fail"
        } else {
            "conditional"
        }
    };
    assert_eq!(d["terms"]["k0"]["verdict"], verdict("k0"));
    assert_eq!(d["terms"]["kp"]["verdict"], verdict("kp"));
    assert_eq!(d["terms"]["k0"]["verdict"], "pass");
    // kp − U = 6.2738e-3 − 3.6e-5 lies above the limit plus U: fail.
    assert_eq!(d["terms"]["kp"]["verdict"], "fail", "{d}");
    assert_eq!(d["verdict"], "fail");
    assert_eq!(
        r["due_at"], "2006-01-28T00:00:00.000000Z",
        "2005-08-01 plus 180 days"
    );
    let s: Value = app
        .get("/v1/sensors/PAPER-2005", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(
        (
            s["sensor_type"].as_str(),
            s["latest_verdict"].as_str(),
            s["status"].as_str()
        ),
        (Some("NAV"), Some("fail"), Some("failed"))
    );
    let failed: Value = app
        .get("/v1/sensors?status=failed", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(failed["items"][0]["sensor_id"], "PAPER-2005");
    let ok: Value = app
        .get("/v1/sensors?status=ok", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(ok["items"], json!([]));
    problem(
        app.get("/v1/sensors?status=bad", ADMIN).await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    let found: Value = app
        .get("/v1/sensors?search=paper-&status=failed", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(found["items"][0]["sensor_id"], "PAPER-2005");
    let none: Value = app
        .get("/v1/sensors?search=GYRO", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(none["items"], json!([]));
    for bad in ["%25", "a%20b", ""] {
        let p = problem(
            app.get(&format!("/v1/sensors?search={bad}"), ADMIN).await,
            StatusCode::BAD_REQUEST,
        )
        .await;
        assert_eq!(p["parameter"], "search", "{bad}");
    }
}

/// A type changed later never rewrites a stored decision; a submission
/// naming an unknown type, or a type limiting a term the model lacks, is 422.
#[rstest]
#[tokio::test]
async fn decisions_are_immutable_and_types_must_fit(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    put(&app, "/v1/sensor-types/NAV", ADMIN, &nav_type()).await;
    let mut body = submission("IMM-1", "2026-01-01T00:00:00Z", 4);
    body["sensor_type"] = json!("NAV");
    let first = app.submit(ADMIN, &body).await;
    let mut looser = nav_type();
    looser["limits"]["kp"] = json!({"min": -1, "max": 1});
    looser["decision_rule"] = json!("simple");
    put(&app, "/v1/sensor-types/NAV", ADMIN, &looser).await;
    let again: Value = app
        .get(
            &format!("/v1/calibrations/{}", first["id"].as_str().unwrap()),
            ADMIN,
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(again["decision"], first["decision"]);
    body["sensor_type"] = json!("NOPE");
    let p = problem(
        app.post("/v1/calibrations", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/sensor_type"]);
    put(
        &app,
        "/v1/sensor-types/KO",
        ADMIN,
        &json!({"unit": "mA", "limits": {"ko": {"max": 1}}, "decision_rule": "simple"}),
    )
    .await;
    body["sensor_type"] = json!("KO");
    let p = problem(
        app.post("/v1/calibrations", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/model"]);
}

/// As found: the second calibration's position means against the first
/// calibration's model, computed here from the submitted readings.
#[rstest]
#[tokio::test]
async fn a_later_calibration_is_found_against_the_previous_one(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let first = app
        .submit(ADMIN, &submission("AF-1", "2026-01-01T00:00:00Z", 4))
        .await;
    assert_eq!(first["as_found"], Value::Null);
    let mut later = submission("AF-1", "2026-06-01T00:00:00Z", 6);
    // The sensor drifted: +2e-5 on every output.
    for run in later["runs"].as_array_mut().unwrap() {
        for samples in run["readings"].as_array_mut().unwrap() {
            for x in samples.as_array_mut().unwrap() {
                *x = json!(f(x) + 2e-5);
            }
        }
    }
    let second = app.submit(ADMIN, &later).await;
    let af = &second["as_found"];
    assert_eq!(af["previous_calibration_id"], first["id"]);
    let k = &first["fused"]["coefficients"];
    let positions = second["positions"].as_array().unwrap();
    let mut max = 0.0f64;
    for (r, p) in positions.iter().enumerate() {
        let samples: Vec<f64> = later["runs"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|run| run["readings"][r].as_array().unwrap().iter().map(f))
            .collect();
        let mean = samples.iter().sum::<f64>() / samples.len() as f64;
        let model = f(&k["k0"]) + f(&k["ki"]) * f(&p["a"][0]) + f(&k["kp"]) * f(&p["a"][1]);
        let err = mean - model;
        close(&af["positions"][r]["error_output"], err, 1e-12);
        close(&af["positions"][r]["error_g"], err / f(&k["ki"]), 1e-12);
        max = max.max((err / f(&k["ki"])).abs());
    }
    close(&af["max_abs_error_g"], max, 1e-12);
    // An earlier calibration submitted afterwards is found against nothing
    // older than it.
    let older = app
        .submit(ADMIN, &submission("AF-1", "2025-06-01T00:00:00Z", 4))
        .await;
    assert_eq!(older["as_found"], Value::Null);
    // One performed between the first and the second is found against the
    // first: the sensor's latest (the second) is not "before" it.
    let between = app
        .submit(ADMIN, &submission("AF-1", "2026-03-01T00:00:00Z", 4))
        .await;
    assert_eq!(between["as_found"]["previous_calibration_id"], first["id"]);
    // And one after them all, against the latest, whichever was stored last.
    let last = app
        .submit(ADMIN, &submission("AF-1", "2026-09-01T00:00:00Z", 4))
        .await;
    assert_eq!(last["as_found"]["previous_calibration_id"], second["id"]);
}

/// Stability over four calibrations, against statistics computed here from
/// the fused values the calibrations returned.
#[rstest]
#[tokio::test]
async fn stability_summarises_the_history(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let days = ["2026-01-01", "2026-04-01", "2026-07-01", "2026-10-01"];
    let mut values = Vec::new();
    let mut times = Vec::new();
    let mut ses = Vec::new();
    for (n, day) in days.iter().enumerate() {
        let mut body = submission("STB-1", &format!("{day}T00:00:00Z"), 4 + 2 * n);
        for run in body["runs"].as_array_mut().unwrap() {
            for samples in run["readings"].as_array_mut().unwrap() {
                for x in samples.as_array_mut().unwrap() {
                    *x = json!(f(x) + 1e-5 * n as f64);
                }
            }
        }
        let r = app.submit(ADMIN, &body).await;
        values.push(f(&r["fused"]["coefficients"]["k0"]));
        ses.push(f(&r["fused"]["std_errors"]["k0"]));
        let t = time::OffsetDateTime::parse(
            &format!("{day}T00:00:00Z"),
            &time::format_description::well_known::Rfc3339,
        )
        .unwrap();
        times.push(t.unix_timestamp() as f64 / (365.25 * 86400.0));
    }
    let s: Value = app
        .get("/v1/sensors/STB-1/stability", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(s["calibrations"], 4);
    let k0 = &s["terms"]["k0"];
    let n = 4.0;
    let mean = values.iter().sum::<f64>() / n;
    let tm = times.iter().sum::<f64>() / n;
    let stt: f64 = times.iter().map(|t| (t - tm).powi(2)).sum();
    let slope = times
        .iter()
        .zip(&values)
        .map(|(t, x)| (t - tm) * (x - mean))
        .sum::<f64>()
        / stt;
    let rss: f64 = times
        .iter()
        .zip(&values)
        .map(|(t, x)| (x - mean - slope * (t - tm)).powi(2))
        .sum();
    let se = (rss / 2.0).sqrt() / stt.sqrt();
    close(&k0["mean"], mean, 1e-15);
    close(&k0["drift_per_year"], slope, 1e-9 * slope.abs());
    close(&k0["drift_std_error"], se, 1e-6 * se);
    let mr = values.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>() / 3.0;
    close(&k0["control"]["moving_range_mean"], mr, 1e-15);
    close(&k0["control"]["upper"], mean + 2.66 * mr, 1e-15);
    close(&k0["latest_change"], values[3] - values[2], 1e-15);
    close(
        &k0["latest_change_expanded"],
        2.0 * (ses[3].powi(2) + ses[2].powi(2)).sqrt(),
        1e-15,
    );
    // A window.
    let w: Value = app
        .get(
            "/v1/sensors/STB-1/stability?from=2026-03-01T00:00:00Z&to=2026-08-01T00:00:00Z",
            ADMIN,
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(w["calibrations"], 2);
    assert_eq!(w["terms"]["k0"]["drift_per_year"], Value::Null);
    problem(
        app.get("/v1/sensors/NONE/stability", ADMIN).await,
        StatusCode::NOT_FOUND,
    )
    .await;
}

/// Runs at three temperatures: the sensitivity is the least-squares slope
/// of the per-run coefficients on temperature, computed here.
#[rstest]
#[tokio::test]
async fn runs_at_several_temperatures_give_sensitivities(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let mut body = submission("TMP-1", "2026-01-01T00:00:00Z", 6);
    let temps = [15.0, 15.0, 25.0, 25.0, 35.0, 35.0];
    for (run, t) in body["runs"].as_array_mut().unwrap().iter_mut().zip(temps) {
        run["temperature_c"] = json!(t);
        for samples in run["readings"].as_array_mut().unwrap() {
            for x in samples.as_array_mut().unwrap() {
                *x = json!(f(x) + 3e-6 * (t - 25.0));
            }
        }
    }
    let r = app.submit(ADMIN, &body).await;
    let k0: Vec<f64> = r["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| f(&x["coefficients"]["k0"]))
        .collect();
    let (tm, xm) = (25.0, k0.iter().sum::<f64>() / 6.0);
    let stt: f64 = temps.iter().map(|t| (t - tm).powi(2)).sum();
    let slope = temps
        .iter()
        .zip(&k0)
        .map(|(t, x)| (t - tm) * (x - xm))
        .sum::<f64>()
        / stt;
    let t = &r["temperature"]["k0"];
    close(&t["per_kelvin"], slope, 1e-12);
    assert!(
        (slope - 3e-6).abs() < 2e-7,
        "the injected sensitivity comes back: {slope}"
    );
    close(&t["reference_c"], 25.0, 1e-12);
    close(&t["value_at_reference"], xm, 1e-15);
    assert!(t["std_error"].is_number());
    assert_eq!(r["temperatures_c"], json!(temps));
    // Some runs with a temperature and some without: refused.
    body["runs"][0]["temperature_c"] = Value::Null;
    let p = problem(
        app.post("/v1/calibrations", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/runs/0/temperature_c"]);
    // One temperature for all: no sensitivity.
    let plain = app
        .submit(ADMIN, &submission("TMP-2", "2026-01-01T00:00:00Z", 4))
        .await;
    assert!(plain.get("temperature").is_none());
}

/// Assigning a type to a sensor (admin): it applies to the next
/// calibrations.
#[rstest]
#[tokio::test]
async fn a_sensor_can_be_given_a_type(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    put(&app, "/v1/sensor-types/NAV", ADMIN, &nav_type()).await;
    app.submit(ADMIN, &submission("AS-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let s: Value = put(
        &app,
        "/v1/sensors/AS-1",
        ADMIN,
        &json!({"sensor_type": "NAV"}),
    )
    .await
    .json()
    .await
    .unwrap();
    assert_eq!(
        (s["sensor_type"].as_str(), s["status"].as_str()),
        (Some("NAV"), Some("unknown"))
    );
    let next = app
        .submit(ADMIN, &submission("AS-1", "2026-02-01T00:00:00Z", 4))
        .await;
    assert_eq!(next["sensor_type"], "NAV");
    assert!(next["decision"].is_object());
    problem(
        put(
            &app,
            "/v1/sensors/AS-1",
            ADMIN,
            &json!({"sensor_type": "NOPE"}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    problem(
        put(
            &app,
            "/v1/sensors/NONE",
            ADMIN,
            &json!({"sensor_type": "NAV"}),
        )
        .await,
        StatusCode::NOT_FOUND,
    )
    .await;
    let reader = app.token("reader", None).await;
    problem(
        put(
            &app,
            "/v1/sensors/AS-1",
            &reader,
            &json!({"sensor_type": "NAV"}),
        )
        .await,
        StatusCode::FORBIDDEN,
    )
    .await;
}

/// Quality flags: a noisy run is named, and the numbers are those of the
/// same submission without flags (flags never change a number).
#[rstest]
#[tokio::test]
async fn a_noisy_run_is_flagged(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let mut body = submission("Q-1", "2026-01-01T00:00:00Z", 6);
    body["positions"] =
        json!([0, 45, 90, 135, 180, 225, 270, 315].map(|d| json!({"angle_deg": d})));
    let (k0, ki, kp) = (-8.4e-4, -1.216, 6.2e-3);
    for (j, run) in body["runs"].as_array_mut().unwrap().iter_mut().enumerate() {
        let amp = if j == 4 { 2e-4 } else { 1e-5 };
        let readings: Vec<Value> = (0..8)
            .map(|p| {
                let th = (45.0 * p as f64).to_radians();
                json!([k0 - ki * th.sin() + kp * th.cos() + amp * ((j * 8 + p) as f64 * 1.3).sin()])
            })
            .collect();
        run["readings"] = json!(readings);
    }
    let r = app.submit(ADMIN, &body).await;
    let w = &r["quality"]["warnings"];
    assert_eq!(w.as_array().unwrap().len(), 1, "{w}");
    assert_eq!(
        (w[0]["kind"].as_str(), w[0]["run"].as_u64()),
        (Some("noisy_run"), Some(4))
    );
    assert_eq!(r["quality"]["condition_number"], r["condition_number"]);
}

/// Coefficients a control system can act on: a failed calibration and an
/// overdue one are served with `usable: false` and their reasons, refused
/// with a 409 to a client that requires usable ones, and compensation says
/// which cross-axis inputs it took as 0.
#[rstest]
#[tokio::test]
async fn unusable_coefficients_say_so_and_are_refused_on_request(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    // The paper's k0 (−6.8e-4) is below this type's minimum: fail.
    let strict = json!({"unit": "output", "limits": {"k0": {"min": 0.0, "max": 1e-3}}, "decision_rule": "simple"});
    assert_eq!(
        put(&app, "/v1/sensor-types/STRICT", ADMIN, &strict)
            .await
            .status(),
        StatusCode::CREATED
    );
    let mut body = paper();
    body["sensor_type"] = json!("STRICT");
    let id = app.submit(ADMIN, &body).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let reader = app.token("reader", None).await;
    let c = app
        .get_json("/v1/sensors/PAPER-2005/coefficients", &reader)
        .await;
    assert_eq!(c["calibration_id"], id.as_str());
    assert_eq!(
        (c["verdict"].as_str(), c["status"].as_str()),
        (Some("fail"), Some("failed"))
    );
    assert_eq!(c["usable"], false);
    assert_eq!(c["reasons"][0]["reason"], "failed");
    assert!(c["due_at"].is_string());
    let p = problem(
        app.get(
            "/v1/sensors/PAPER-2005/coefficients?require=usable",
            &reader,
        )
        .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert_eq!(p["type"], "urn:accelcal:problem:not-usable");
    assert!(p["detail"].as_str().unwrap().contains("verdict"), "{p}");
    let p = problem(
        app.post(
            "/v1/sensors/PAPER-2005/compensate?require=usable",
            &reader,
            &json!({"outputs": [0.5]}),
        )
        .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert_eq!(p["type"], "urn:accelcal:problem:not-usable");
    let r = app
        .post(
            "/v1/sensors/PAPER-2005/compensate",
            &reader,
            &json!({"outputs": [0.5]}),
        )
        .await;
    assert_eq!(r.status(), StatusCode::OK);
    let r: Value = r.json().await.unwrap();
    assert_eq!(
        (r["usable"].as_bool(), r["status"].as_str()),
        (Some(false), Some("failed"))
    );
    // The paper's model has kp: a_p was taken as 0 and the answer says so.
    assert_eq!(r["assumed_zero"], json!(["a_p"]));
    let r: Value = app
        .post(
            "/v1/sensors/PAPER-2005/compensate",
            &reader,
            &json!({"outputs": [0.5], "a_p": [0.0]}),
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["assumed_zero"], json!([]));
    // A requirement other than `usable` is a 400 naming the parameter.
    let p = problem(
        app.get("/v1/sensors/PAPER-2005/coefficients?require=fresh", &reader)
            .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "require");

    // Overdue: a one-day interval, performed three days ago; it passes.
    let daily = json!({"unit": "mA", "limits": {"k0": {"min": -1e-3, "max": 1e-3}}, "decision_rule": "simple", "interval_days": 1});
    put(&app, "/v1/sensor-types/DAILY", ADMIN, &daily).await;
    let mut body = submission("OLD-1", "2000-01-01T00:00:00Z", 6);
    let three_days_ago = accelcal::domain::timestamp::Timestamp::now().plus_seconds(-3 * 86_400);
    body["performed_at"] = json!(three_days_ago.to_string());
    body["sensor_type"] = json!("DAILY");
    app.submit(ADMIN, &body).await;
    let c = app
        .get_json("/v1/sensors/OLD-1/coefficients", &reader)
        .await;
    assert_eq!(
        (c["verdict"].as_str(), c["status"].as_str()),
        (Some("pass"), Some("overdue"))
    );
    assert_eq!(c["usable"], false);
    assert_eq!(c["reasons"][0]["reason"], "overdue");
    problem(
        app.get("/v1/sensors/OLD-1/coefficients?require=usable", &reader)
            .await,
        StatusCode::CONFLICT,
    )
    .await;
    // A usable one is served as usual when required (due within a day:
    // due soon, and usable).
    let mut body = submission("NEW-1", "2000-01-01T00:00:00Z", 6);
    body["performed_at"] = json!(accelcal::domain::timestamp::Timestamp::now().to_string());
    body["sensor_type"] = json!("DAILY");
    app.submit(ADMIN, &body).await;
    let c = app
        .get_json("/v1/sensors/NEW-1/coefficients?require=usable", &reader)
        .await;
    assert_eq!(
        (c["usable"].as_bool(), c["status"].as_str()),
        (Some(true), Some("due_soon"))
    );
}

/// A systematic misfit the runs share: the model `k0 ki kp` on eight
/// positions whose outputs hold an unmodelled `kii`, two samples a position.
/// The result says lack of fit (F, ν1, ν2, p), names `kii`, and the budget
/// carries the model component in quadrature.
#[rstest]
#[tokio::test]
async fn a_misfit_is_flagged_and_enters_the_budget(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let body = misfit_submission("MISFIT-1");
    let r = app.submit(ADMIN, &body).await;
    let lof = &r["quality"]["lack_of_fit"];
    assert_eq!(lof["status"], "tested", "{lof}");
    assert_eq!(
        (lof["df1"].as_u64(), lof["df2"].as_u64()),
        (Some(30), Some(48))
    );
    assert!(f(&lof["p_value"]) < 1e-3, "{lof}");
    let kinds: Vec<&str> = r["quality"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["kind"].as_str().unwrap())
        .collect();
    assert!(kinds.contains(&"lack_of_fit"), "{kinds:?}");
    assert!(
        r["quality"]["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w["kind"] == "unmodelled_term" && w["term"] == "kii"),
        "{}",
        r["quality"]["warnings"]
    );
    for term in ["k0", "ki", "kp"] {
        let b = &r["uncertainty"]["terms"][term];
        let parts = ["statistical", "indexing", "gravity", "model"].map(|k| f(&b[k]));
        assert!(parts[3] > 0.0, "{term}: {b}");
        let rss = parts.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(
            (f(&b["combined"]) - rss).abs() <= 1e-12 * rss,
            "{term}: {b}"
        );
    }
    // The model component dominates the fused standard error: the misfit is
    // the same in every run, so fusion cannot see it.
    let b = &r["uncertainty"]["terms"]["k0"];
    assert!(f(&b["model"]) > 10.0 * f(&b["statistical"]), "{b}");
}

/// Units are compared: a typed sensor's calibrations must be in its type's
/// unit; as found across a change of unit is null with the reason; stability
/// reports one unit, the latest calibration's, and counts what it left out.
#[rstest]
#[tokio::test]
async fn units_are_compared_and_never_mixed(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    put(&app, "/v1/sensor-types/NAV", ADMIN, &nav_type()).await;
    // The type's limits are in mA: a submission in A for it is refused.
    let mut amps = submission("U-1", "2026-01-01T00:00:00Z", 4);
    amps["unit"] = json!("A");
    amps["sensor_type"] = json!("NAV");
    let p = problem(
        app.post("/v1/calibrations", ADMIN, &amps).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(p["errors"][0]["pointer"], "/unit");
    let detail = p["errors"][0]["detail"].as_str().unwrap();
    assert!(
        detail.contains("`A`") && detail.contains("`mA`") && detail.contains("NAV"),
        "{detail}"
    );
    // Untyped, a sensor may change unit; as found says why it is null.
    app.submit(ADMIN, &submission("U-2", "2026-01-01T00:00:00Z", 4))
        .await;
    app.submit(ADMIN, &submission("U-2", "2026-02-01T00:00:00Z", 4))
        .await;
    let mut later = submission("U-2", "2026-03-01T00:00:00Z", 4);
    later["unit"] = json!("A");
    let r = app.submit(ADMIN, &later).await;
    assert!(r["as_found"].is_null());
    let note = r["as_found_note"].as_str().unwrap();
    assert!(note.contains("`mA`") && note.contains("`A`"), "{note}");
    let s = app.get_json("/v1/sensors/U-2/stability", ADMIN).await;
    assert_eq!(
        (
            s["unit"].as_str(),
            s["calibrations"].as_u64(),
            s["other_units"].as_u64()
        ),
        (Some("A"), Some(1), Some(2))
    );
    // Back in mA: the mA ones are the series again, the A one left out.
    app.submit(ADMIN, &submission("U-2", "2026-04-01T00:00:00Z", 4))
        .await;
    let s = app.get_json("/v1/sensors/U-2/stability", ADMIN).await;
    assert_eq!(
        (
            s["unit"].as_str(),
            s["calibrations"].as_u64(),
            s["other_units"].as_u64()
        ),
        (Some("mA"), Some(3), Some(1))
    );
    assert!(s["terms"]["k0"]["mean"].is_number());
}

/// Each position's samples replaced by their summary: mean, sample standard
/// deviation and count (computed here, two-pass).
fn summarised(body: &Value) -> Value {
    let mut body = body.clone();
    for run in body["runs"].as_array_mut().unwrap() {
        for reading in run["readings"].as_array_mut().unwrap() {
            let xs: Vec<f64> = reading.as_array().unwrap().iter().map(f).collect();
            let n = xs.len() as f64;
            let mean = xs.iter().sum::<f64>() / n;
            let ss: f64 = xs.iter().map(|x| (x - mean).powi(2)).sum();
            let std = if xs.len() > 1 {
                (ss / (n - 1.0)).sqrt()
            } else {
                0.0
            };
            *reading = json!({"mean": mean, "std": std, "count": xs.len()});
        }
    }
    body
}

#[track_caller]
fn same(a: &Value, b: &Value, what: &str) {
    let (x, y) = (f(a), f(b));
    assert!(
        (x - y).abs() <= 1e-12 * x.abs().max(1e-300),
        "{what}: {x:e} vs {y:e}"
    );
}

/// A station that averages on board sends each position's mean, standard
/// deviation and count, as JSON or CSV: the calibration — coefficients,
/// standard errors, pure error and lack of fit — is the one its samples give.
#[rstest]
#[tokio::test]
async fn summaries_calibrate_as_their_samples_do(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let samples = misfit_submission("SUMMARY-SAMPLES");
    let mut json_summaries = summarised(&samples);
    json_summaries["sensor_id"] = json!("SUMMARY-JSON");
    let mut csv =
        String::from("# sensor_id: SUMMARY-CSV\n# unit: mA\nrun,angle_deg,mean,std,count\n");
    for (j, run) in json_summaries["runs"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        for (p, r) in run["readings"].as_array().unwrap().iter().enumerate() {
            let angle = &samples["positions"][p]["angle_deg"];
            csv += &format!(
                "{j},{angle},{:e},{:e},{}\n",
                f(&r["mean"]),
                f(&r["std"]),
                r["count"]
            );
        }
    }
    let a = app.submit(ADMIN, &samples).await;
    let b = app.submit(ADMIN, &json_summaries).await;
    let res = app
        .client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(ADMIN)
        .header("content-type", "text/csv")
        .body(csv)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::CREATED);
    let c: Value = res.json().await.unwrap();
    assert_eq!(a["quality"]["lack_of_fit"]["status"], "tested");
    for r in [&b, &c] {
        for term in ["k0", "ki", "kp"] {
            for block in ["coefficients", "std_errors"] {
                same(&a["fused"][block][term], &r["fused"][block][term], term);
            }
        }
        let (pa, pr) = (&a["quality"]["pure_error"], &r["quality"]["pure_error"]);
        assert_eq!(pa["dof"], pr["dof"]);
        same(&pa["std"], &pr["std"], "pure error");
        let (la, lr) = (&a["quality"]["lack_of_fit"], &r["quality"]["lack_of_fit"]);
        assert_eq!((&la["df1"], &la["df2"]), (&lr["df1"], &lr["df2"]));
        assert!(
            (f(&la["f"]) - f(&lr["f"])).abs() <= 1e-9 * f(&la["f"]),
            "{la} {lr}"
        );
    }
}

/// A real static window: 100 000 samples at one position of one run (1 000 s
/// at 100 Hz), sent gzip-compressed, is a submission.
#[tokio::test]
async fn a_position_may_hold_a_hundred_thousand_samples() {
    let app = TestApp::spawn(Sqlite).await;
    let mut body = submission("LONG-WINDOW", "2026-01-01T00:00:00Z", 4);
    let first = f(&body["runs"][0]["readings"][0][0]);
    let window: Vec<f64> = (0..100_000)
        .map(|k| first + 1e-6 * (f64::from(k) * 0.37).sin())
        .collect();
    body["runs"][0]["readings"][0] = json!(window);
    let plain = serde_json::to_vec(&body).unwrap();
    let res = app
        .client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(ADMIN)
        .header("content-type", "application/json")
        .header("content-encoding", "gzip")
        .body(gzip(&plain))
        .send()
        .await
        .unwrap();
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{r}");
    // The window's 99 999 degrees of freedom are in the pure error.
    let runs = body["runs"].as_array().unwrap();
    let dof: usize = runs
        .iter()
        .flat_map(|run| run["readings"].as_array().unwrap())
        .map(|s| s.as_array().unwrap().len() - 1)
        .sum();
    assert_eq!(r["quality"]["pure_error"]["dof"], json!(dof));
    assert!(dof >= 99_999);
    // One more sample is refused, naming the position.
    body["runs"][0]["readings"][0]
        .as_array_mut()
        .unwrap()
        .push(json!(first));
    let res = app.post("/v1/calibrations", ADMIN, &body).await;
    let p = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(p["errors"][0]["pointer"], "/runs/0/readings/0");
}

/// The suites' clean submission is clean by the service's own tests: its
/// replicates scatter as much as its runs, so lack of fit is tested and not
/// found, and no warning is raised — tests that need a misfit ask for one
/// (`misfit_submission`).
#[tokio::test]
async fn the_clean_test_submission_raises_no_warning() {
    let app = TestApp::spawn(Sqlite).await;
    let r = app
        .submit(ADMIN, &submission("CLEAN-1", "2026-01-01T00:00:00Z", 8))
        .await;
    let lof = &r["quality"]["lack_of_fit"];
    assert_eq!(lof["status"], "tested", "{lof}");
    assert!(f(&lof["p_value"]) > 0.001, "{lof}");
    assert_eq!(r["quality"]["warnings"], json!([]));
    for term in ["k0", "ki", "kp"] {
        assert_eq!(
            r["uncertainty"]["terms"][term]["model"],
            json!(0.0),
            "{term}"
        );
    }
}
