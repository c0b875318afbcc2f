//! A temperature model's reference standards (issue 45 item 4), on both
//! engines: the stand and thermometer it names are resolved and recorded
//! as a single axis's are; the thermometer's reading uncertainty `u_T`
//! enters every coefficient read at a temperature as `u_T · |dc/dT|`
//! beside the polynomial's own `√(vᵀ C v)` — computed here from the
//! stored model's JSON, the slope `Σ d a_d x^(d−1)` by hand — in the
//! coefficients, and in the model's judgement across its range; a
//! nonconformity of the thermometer holds a model made with it, and a
//! model made after it was found is refused naming the thermometer.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal::domain::timestamp::Timestamp;
use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

use crate::thermal::{CHAMBER, body, f};

pub(crate) const DAY: i64 = 86_400;
/// The thermometer's standard uncertainty, K.
const U_T: f64 = 0.2;

pub(crate) fn ago(seconds: i64) -> String {
    Timestamp::now().plus_seconds(-seconds).to_string()
}

/// A standard of `kind` calibrated 200 days ago, due in 300, with `extra`.
pub(crate) fn standard(kind: &str, extra: Value) -> Value {
    let mut s = json!({
        "kind": kind,
        "description": format!("the lab's {kind}"),
        "certificate": {"number": format!("CAL-{kind}"), "issued_by": "NML",
                        "calibrated_at": ago(200 * DAY)},
        "due_at": Timestamp::now().plus_seconds(300 * DAY).to_string(),
        "traceability": "NML chain",
    });
    s.as_object_mut()
        .unwrap()
        .extend(extra.as_object().unwrap().clone());
    s
}

/// The stand `DH-1` and the thermometer `TH-1`, read to `u_t` K,
/// recorded (each calibrated 200 days ago).
pub(crate) async fn stand_and_thermometer(app: &TestApp, u_t: f64) {
    for (id, s) in [
        (
            "DH-1",
            standard("tumble_stand", json!({"angle_std_arcsec": 2.0})),
        ),
        (
            "TH-1",
            standard("thermometer", json!({"temperature_std_c": u_t})),
        ),
    ] {
        let res = app.put(&format!("/v1/standards/{id}"), ADMIN, &s).await;
        assert_eq!(res.status(), StatusCode::CREATED);
    }
}

/// `(c(t), √(vᵀ C v), c′(t))` of the polynomial `p` (a stored model's
/// JSON): the slope `Σ d a_d x^(d−1)` by hand.
pub(crate) fn read(p: &Value, t: f64) -> (f64, f64, f64) {
    let (value, u) = crate::thermal_stored::evaluated(p, t);
    let x = t - f(&p["reference_c"]);
    let a = p["coefficients"].as_array().unwrap();
    let slope = (1..a.len())
        .map(|d| d as f64 * f(&a[d]) * x.powi(d as i32 - 1))
        .sum();
    (value, u, slope)
}

async fn stored(app: &TestApp, sensor: &str, standards: Value, performed: &str) -> Value {
    let mut b = body(&CHAMBER);
    b["sensor_id"] = json!(sensor);
    b["performed_at"] = json!(performed);
    if !standards.is_null() {
        b["standards"] = standards;
    }
    let res = app.post("/v1/calibrations/thermal", ADMIN, &b).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    res.json().await.unwrap()
}

#[rstest]
#[tokio::test]
async fn a_models_thermometer_is_in_its_budget_and_its_nonconformity_holds_it(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let mut app = TestApp::spawn(engine).await;
    stand_and_thermometer(&app, U_T).await;
    let with = stored(
        &app,
        "MEMS-TH",
        json!({"stand": "DH-1", "thermometer": "TH-1"}),
        &ago(40 * DAY),
    )
    .await;
    crate::conforms_to("StoredThermal", &with);
    let without = stored(&app, "MEMS-NO", Value::Null, &ago(40 * DAY)).await;
    let roles: Vec<&str> = with["standards"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| u["role"].as_str().unwrap())
        .collect();
    assert_eq!(roles, ["stand", "thermometer"]);
    assert_eq!(with["thermal"]["thermometer_std_c"], U_T);
    assert!(without.get("standards").is_none(), "{without}");
    assert!(without["thermal"].get("thermometer_std_c").is_none());
    // The same runs fit the same polynomials: only the budget differs.
    assert_eq!(
        with["thermal"]["coefficients"],
        without["thermal"]["coefficients"]
    );

    for t in [-15.0, 20.0, 33.0, 55.0] {
        let at = |sensor: &str| {
            let app = &app;
            let path = format!("/v1/sensors/{sensor}/coefficients?temperature_c={t}");
            async move { app.get_json(&path, ADMIN).await }
        };
        let (r, plain) = (at("MEMS-TH").await, at("MEMS-NO").await);
        assert_eq!(r["temperature"]["thermometer_std_c"], U_T, "{r}");
        assert!(plain["temperature"].get("thermometer_std_c").is_none());
        for term in ["k0", "ki", "kp"] {
            let (c, u_fit, slope) = read(&with["thermal"]["coefficients"][term], t);
            let want = (u_fit * u_fit + (U_T * slope).powi(2)).sqrt();
            let got = f(&r["std_errors"][term]);
            assert!(
                (got - want).abs() <= 1e-12 * want,
                "u({term}({t})): {got} against {want}"
            );
            assert_eq!(f(&r["coefficients"][term]), f(&plain["coefficients"][term]));
            assert!((f(&r["coefficients"][term]) - c).abs() <= 1e-12 * c.abs());
            assert!(
                (f(&plain["std_errors"][term]) - u_fit).abs() <= 1e-12 * u_fit,
                "{term}({t}) without a thermometer"
            );
        }
        // From 20 °C up k0 moves by 2e-5 V/K and more: u_T · c′
        // outweighs the fit's own (near −13 °C, where c′ = 0, it does not).
        let (_, u_fit, slope) = read(&with["thermal"]["coefficients"]["k0"], t);
        if t >= 20.0 {
            assert!(
                U_T * slope.abs() > 10.0 * u_fit,
                "k0 at {t}: {slope} {u_fit}"
            );
        }
    }

    // The thermometer found nonconforming yesterday, last known good 100
    // days ago: the model made with it 40 days ago is held and listed; one
    // made with it now is refused naming it; the other model is untouched.
    let nc = json!({"found_at": ago(DAY), "last_known_good_at": ago(100 * DAY),
        "reason": "Reads 0.8 K high below 0 °C."});
    let res = app
        .post("/v1/standards/TH-1/nonconformity", ADMIN, &nc)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let state = |id: &Value| {
        let path = format!("/v1/calibrations/{}/signatures", id.as_str().unwrap());
        let app = &app;
        async move { app.get_json(&path, ADMIN).await["state"].clone() }
    };
    assert_eq!(state(&with["id"]).await, "under_review");
    assert_eq!(state(&without["id"]).await, "submitted");
    let affected = app.get_json("/v1/standards/TH-1/affected", ADMIN).await;
    assert_eq!(
        affected["nonconformities"][0]["calibrations"][0]["calibration_id"], with["id"],
        "{affected}"
    );
    let mut now = body(&CHAMBER);
    now["standards"] = json!({"stand": "DH-1", "thermometer": "TH-1"});
    let p = problem(
        app.post("/v1/calibrations/thermal", ADMIN, &now).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/standards/thermometer"], "{p}");
    app.stop().await;
    crate::audit::verifies(app.database.clone()).await;
}
