//! A triad's temperature model stored as a calibration (issue 45 items 1
//! and 6), `POST /v1/calibrations/thermal/triad`, on both engines: the
//! model stored is the one `POST /v1/identify/thermal/triad` fits; its
//! elements are the model at `T_ref`; the coefficients at a temperature
//! are its polynomials evaluated — computed here from the stored JSON —
//! and compensation there is `g = S(T)⁻¹ (u − b(T))`, solved here by
//! Cramer's rule; read back through a restart; outside the range refused
//! unless extrapolation is allowed; its export is the model's thermal
//! parameters; its page and certificate list the polynomials; what it
//! cannot use is refused.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

use crate::thermal_triad::{body, body_with, f};

const CHAMBER: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];

/// `(e(t), u(e(t)))` of the polynomial `p` (a stored model's JSON).
fn read(p: &Value, t: f64) -> (f64, f64) {
    crate::thermal_stored::evaluated(p, t)
}

/// `b(t)` and `S(t)` of the stored model `m`.
fn at(m: &Value, t: f64) -> ([f64; 3], [[f64; 3]; 3]) {
    let b = std::array::from_fn(|i| read(&m["b"][i], t).0);
    let s = std::array::from_fn(|i| std::array::from_fn(|j| read(&m["S"][i][j], t).0));
    (b, s)
}

/// `x` with `S x = r`, by Cramer's rule.
fn solve(s: [[f64; 3]; 3], r: [f64; 3]) -> [f64; 3] {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(s);
    std::array::from_fn(|k| {
        let mut m = s;
        for i in 0..3 {
            m[i][k] = r[i];
        }
        det(m) / d
    })
}

fn near(got: f64, want: f64, what: &str) {
    assert!(
        (got - want).abs() <= 1e-9 * want.abs().max(1e-6),
        "{what}: {got} against {want}"
    );
}

#[rstest]
#[tokio::test]
async fn a_stored_triad_model_is_read_and_compensates_at_a_temperature(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let mut app = TestApp::spawn(engine).await;
    // S constant over temperature: PX4 carries the model.
    let b = body_with(&CHAMBER, 0.0);
    let fitted: Value = app
        .post("/v1/identify/thermal/triad", ADMIN, &b)
        .await
        .json()
        .await
        .unwrap();
    let res = app.post("/v1/calibrations/thermal/triad", ADMIN, &b).await;
    let status = res.status();
    let stored: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{stored}");
    crate::conforms_to("StoredThermalTriad", &stored);
    assert_eq!(stored["kind"], "thermal_triad");
    assert_eq!(stored["thermal"], fitted);
    let (tref, range) = (f(&stored["reference_c"]), stored["range_c"].clone());
    let e = &stored["elements"];
    for i in 0..3 {
        assert_eq!(e["b"][i], fitted["b"][i]["coefficients"][0]);
        assert_eq!(e["b_std_errors"][i], fitted["b"][i]["std_uncertainties"][0]);
        for j in 0..3 {
            assert_eq!(e["S"][i][j], fitted["S"][i][j]["coefficients"][0]);
            // T = S⁻¹: S T = I.
            let st: f64 = (0..3).map(|k| f(&e["S"][i][k]) * f(&e["T"][k][j])).sum();
            near(st, if i == j { 1.0 } else { 0.0 }, "S T");
        }
    }
    let id = stored["id"].as_str().unwrap().to_owned();

    // Restarted: everything below is read back from the database.
    app.stop().await;
    let db = app.take_database().unwrap();
    let app = TestApp::spawn_on(&db.url).await;
    let coefficients = "/v1/sensors/IMU-T/coefficients";
    let plain = app.get_json(coefficients, ADMIN).await;
    assert_eq!(plain["triad"], stored["elements"]);
    assert_eq!(plain["temperature"]["temperature_c"], tref);
    let m = &stored["thermal"];
    for t in [-19.9, 33.0, 59.9] {
        let r = app
            .get_json(&format!("{coefficients}?temperature_c={t}"), ADMIN)
            .await;
        assert_eq!(r["temperature"]["temperature_c"], t);
        assert_eq!(r["temperature"]["range_c"], range);
        for i in 0..3 {
            let (v, u) = read(&m["b"][i], t);
            near(f(&r["triad"]["b"][i]), v, &format!("b[{i}]({t})"));
            near(
                f(&r["triad"]["b_std_errors"][i]),
                u,
                &format!("u(b[{i}]({t}))"),
            );
            for j in 0..3 {
                let (v, _) = read(&m["S"][i][j], t);
                near(f(&r["triad"]["S"][i][j]), v, &format!("S[{i}][{j}]({t})"));
            }
        }
    }

    // Compensation at 33 °C, one temperature and one per output.
    let outputs = [[0.31, -0.12, 9.69], [9.93, 0.05, -0.21]];
    let compensate = "/v1/sensors/IMU-T/compensate";
    for temperatures in [json!(33.0), json!([20.0, 45.5])] {
        let r: Value = app
            .post(
                compensate,
                ADMIN,
                &json!({"outputs": outputs, "temperature_c": temperatures}),
            )
            .await
            .json()
            .await
            .unwrap();
        for (k, u) in outputs.iter().enumerate() {
            let t = temperatures.as_f64().unwrap_or_else(|| f(&temperatures[k]));
            let (b, s) = at(m, t);
            let want = solve(s, std::array::from_fn(|i| u[i] - b[i]));
            for i in 0..3 {
                near(f(&r["g"][k][i]), want[i], &format!("g[{k}][{i}] at {t}"));
            }
        }
        assert_eq!(r["temperature"]["temperature_c"], temperatures, "{r}");
    }
    // Outside the range, refused unless allowed; none given, refused.
    for (body, pointer) in [
        (
            json!({"outputs": outputs, "temperature_c": 70.0}),
            "/temperature_c",
        ),
        (json!({"outputs": outputs}), "/temperature_c"),
        (json!({"outputs": [0.3], "temperature_c": 20.0}), "/outputs"),
    ] {
        let p = problem(
            app.post(compensate, ADMIN, &body).await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(pointers(&p), [pointer], "{p}");
    }
    let r: Value = app
        .post(
            compensate,
            ADMIN,
            &json!({"outputs": outputs, "temperature_c": 70.0, "allow_extrapolation": true}),
        )
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["temperature"]["extrapolated"], true, "{r}");
    let p = problem(
        app.get(&format!("{coefficients}?temperature_c=-40"), ADMIN)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("outside"), "{p}");

    // Its export is the model's thermal parameters.
    let res = app
        .get(&format!("/v1/calibrations/{id}/export?format=c"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    assert!(res.text().await.unwrap().contains("ACCELCAL_B_POLY"));
    let res = app
        .get(&format!("/v1/calibrations/{id}/export?format=px4"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    assert!(res.text().await.unwrap().contains("TC_A0_X0_0"));

    // Its page and its (draft) certificate list the polynomials.
    let (session, _) = crate::ui::sign_in(&app, ADMIN).await;
    let page = crate::ui::page(&app, &format!("/ui/calibrations/{id}"), &session).await;
    assert_eq!(page.status(), StatusCode::OK);
    let html = page.text().await.unwrap();
    assert!(html.contains("Triad temperature model of IMU-T"));
    assert!(html.contains("/export/px4"));
    let res = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let cert = res.text().await.unwrap();
    for row in ["b_x_a0", "S_zz_a0", "S_xy_a0"] {
        assert!(cert.contains(&format!("data-element=\"{row}\"")), "{row}");
    }

    // Reprocessing fits the same model again.
    let again = crate::thermal_stored::reprocessed(&app, &id).await;
    assert_eq!(again["thermal"], fitted);
    drop(db);
}

/// What a stored triad model cannot use is refused, naming it: standards
/// and a sensor type not registered, no sensor id; its PX4 export when S
/// drifts more than its uncertainty (409 not-carried).
#[tokio::test]
async fn what_a_stored_triad_model_does_not_apply_is_refused() {
    let app = TestApp::spawn(Sqlite).await;
    let b = body(&CHAMBER);
    for (key, value, pointer) in [
        ("standards", json!({"stand": "DH-1"}), "/standards/stand"),
        ("sensor_type", json!("IMU-NAV"), "/sensor_type"),
    ] {
        let mut with = b.clone();
        with[key] = value;
        let p = problem(
            app.post("/v1/calibrations/thermal/triad", ADMIN, &with)
                .await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(pointers(&p), [pointer], "{p}");
    }
    let mut anonymous = b.clone();
    anonymous.as_object_mut().unwrap().remove("sensor_id");
    let p = problem(
        app.post("/v1/calibrations/thermal/triad", ADMIN, &anonymous)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/sensor_id"], "{p}");
    // Scale factors drifting up to 200 ppm/K: PX4 cannot carry them.
    let mut drifting = b.clone();
    drifting["sensor_id"] = json!("IMU-DRIFT");
    let res = app
        .post("/v1/calibrations/thermal/triad", ADMIN, &drifting)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let id = res.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let p = problem(
        app.get(&format!("/v1/calibrations/{id}/export?format=px4"), ADMIN)
            .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert!(p["type"].as_str().unwrap().ends_with("not-carried"), "{p}");
}
