//! A stored triad's temperature model judged by its sensor type, with its
//! standards (issue 45 item 4, triads), on both engines: each axis's
//! limited terms are elements of `b` and `S` (`k0` is `b_m`; `ki`, `kp`
//! row `m` of `S` at columns `m`, `m + 1`), each judged at every set point
//! by its fused value and `U = 2 se`, and across the range by its
//! polynomial and `U = 2 √(u² + (u_T e′)²)` — both computed here from the
//! stored JSON, the guarded rule written out, the range scanned at 4 001
//! temperatures; the thermometer named enters every element read at a
//! temperature, `T_ref` included; the verdict and due date are the
//! triad's; the certificate states the decision and the standards; a
//! nonconformity of the thermometer holds the model.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal::domain::timestamp::Timestamp;
use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

use crate::thermal_standards::{DAY, ago, read, stand_and_thermometer, standard};
use crate::thermal_stored::guarded;
use crate::thermal_triad::{body, f};

const CHAMBER: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];
/// The thermometer's standard uncertainty, K.
const U_T: f64 = 0.2;
const AXES: [&str; 3] = ["x", "y", "z"];

fn rank(verdict: &str) -> usize {
    ["pass", "conditional", "fail"]
        .iter()
        .position(|x| *x == verdict)
        .unwrap()
}

#[rstest]
#[tokio::test]
async fn a_typed_triads_model_is_judged_element_by_element_with_its_thermometer(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    stand_and_thermometer(&app, U_T).await;
    // b_x rises to 0.122 m/s² at 60 °C (past 0.09), S_zz to 9.909 m/s² per
    // g (past 9.9); the rest stay well inside.
    let limits = json!({"k0": {"min": -0.2, "max": 0.09}, "ki": {"min": 9.7, "max": 9.9},
                        "kp": {"min": -0.01, "max": 0.01}});
    crate::triads::guarded_type(&app, "IMU-THERM", "m/s2", &limits).await;
    let performed = ago(40 * DAY);
    let mut b = body(&CHAMBER);
    b["sensor_type"] = json!("IMU-THERM");
    b["performed_at"] = json!(performed);
    b["standards"] = json!({"stand": "DH-1", "thermometer": "TH-1"});
    // A limit on a term a model over temperature lacks is refused.
    let res = app
        .put(
            "/v1/sensor-types/SECOND-ORDER",
            ADMIN,
            &json!({"unit": "m/s2", "decision_rule": "simple", "interval_days": 180,
                    "limits": {"kii": {"max": 1e-3}}}),
        )
        .await;
    assert!(res.status().is_success());
    let mut kii = b.clone();
    kii["sensor_type"] = json!("SECOND-ORDER");
    kii["sensor_id"] = json!("IMU-K2");
    let p = problem(
        app.post("/v1/calibrations/thermal/triad", ADMIN, &kii)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/sensor_type"], "{p}");
    assert!(p["detail"].to_string().contains("kii"), "{p}");

    let res = app.post("/v1/calibrations/thermal/triad", ADMIN, &b).await;
    let status = res.status();
    let stored: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{stored}");
    crate::conforms_to("StoredThermalTriad", &stored);
    assert_eq!(stored["sensor_type"], "IMU-THERM");
    let roles: Vec<&str> = stored["standards"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| u["role"].as_str().unwrap())
        .collect();
    assert_eq!(roles, ["stand", "thermometer"]);
    let m = &stored["thermal"];
    assert_eq!(m["thermometer_std_c"], U_T);

    // The elements at T_ref carry the thermometer's term: u² = u(a_0)² +
    // (u_T a_1)².
    let tref = f(&stored["reference_c"]);
    for i in 0..3 {
        let (_, u_fit, slope) = read(&m["b"][i], tref);
        let want = (u_fit * u_fit + (U_T * slope).powi(2)).sqrt();
        let got = f(&stored["elements"]["b_std_errors"][i]);
        assert!(
            (got - want).abs() <= 1e-12 * want,
            "u(b[{i}]): {got} {want}"
        );
    }

    // Every limited element, by hand.
    let d = &stored["decision"];
    assert_eq!(d["rule"], "guarded");
    let elements = d["elements"].as_object().unwrap();
    assert_eq!(elements.len(), 9, "{d}");
    let mut model_worst = "pass";
    for (a, axis) in AXES.iter().enumerate() {
        for (term, slot) in [("k0", None), ("ki", Some(a)), ("kp", Some((a + 1) % 3))] {
            // Where the element sits: in the model, and in each set point
            // as a value and its standard error.
            let (name, at) = match slot {
                None => (format!("b_{axis}"), format!("b/{a}")),
                Some(k) => (format!("S_{axis}{}", AXES[k]), format!("S/{a}/{k}")),
            };
            let poly = m.pointer(&format!("/{at}")).unwrap();
            let (matrix, index) = at.split_once('/').unwrap();
            let of_set_point = |sp: &Value| {
                (
                    f(sp.pointer(&format!("/{at}")).unwrap()),
                    f(sp.pointer(&format!("/{matrix}_std_errors/{index}"))
                        .unwrap()),
                )
            };
            let (min, max) = (f(&limits[term]["min"]), f(&limits[term]["max"]));
            let j = &elements[&name];
            let mut verdicts = Vec::new();
            for (s, sp) in m["set_points"].as_array().unwrap().iter().enumerate() {
                let (v, se) = of_set_point(sp);
                let got = &j["set_points"][s];
                assert_eq!(f(&got["value"]), v, "{name} set point {s}");
                assert!((f(&got["expanded"]) - 2.0 * se).abs() <= 1e-15 * se);
                let want = guarded(v, 2.0 * se, min, max);
                assert_eq!(got["verdict"], want, "{name} set point {s}");
                verdicts.push(want);
            }
            // Across the range: the polynomial with the thermometer's
            // term, scanned; the service's worst there is recomputed at
            // its own temperature.
            let (lo, hi) = (f(&poly["range_c"][0]), f(&poly["range_c"][1]));
            let expanded = |t: f64| {
                let (v, u, slope) = read(poly, t);
                (v, 2.0 * (u * u + (U_T * slope).powi(2)).sqrt())
            };
            let mut worst = "pass";
            for i in 0..=4000 {
                let t = lo + (hi - lo) * f64::from(i) / 4000.0;
                let (v, u) = expanded(t);
                let verdict = guarded(v, u, min, max);
                if rank(verdict) > rank(worst) {
                    worst = verdict;
                }
            }
            let range = &j["range"];
            assert_eq!(range["verdict"], worst, "{name}: {j}");
            let (v, u) = expanded(f(&range["temperature_c"]));
            assert!((f(&range["value"]) - v).abs() <= 1e-12 * v.abs().max(1e-3));
            assert!(
                (f(&range["expanded"]) - u).abs() <= 1e-12 * u,
                "{name}: U {} against {u}",
                range["expanded"]
            );
            verdicts.push(worst);
            let overall = verdicts.iter().copied().max_by_key(|v| rank(v)).unwrap();
            assert_eq!(j["worst"]["verdict"], overall, "{name}: {j}");
            if rank(overall) > rank(model_worst) {
                model_worst = overall;
            }
        }
    }
    for (name, verdict) in [("b_x", "fail"), ("S_zz", "fail"), ("b_y", "pass")] {
        assert_eq!(elements[name]["worst"]["verdict"], verdict, "{name}");
    }
    assert!(f(&elements["b_x"]["worst"]["temperature_c"]) > 50.0);
    assert_eq!(d["verdict"], model_worst);
    assert_eq!(model_worst, "fail");

    // The verdict and due date are the triad's.
    let at = |v: &Value| Timestamp::parse(v.as_str().unwrap()).unwrap();
    assert_eq!(
        at(&stored["due_at"]),
        at(&json!(performed)).plus_seconds(365 * DAY)
    );
    let c = app.get_json("/v1/sensors/IMU-T/coefficients", ADMIN).await;
    assert_eq!(c["verdict"], "fail", "{c}");
    assert_eq!(c["usable"], false);

    // Its certificate states the decision, element by element, and the
    // standards.
    let id = stored["id"].as_str().unwrap().to_owned();
    let res = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let cert = res.text().await.unwrap();
    assert!(cert.contains("id=\"thermal-decision\""));
    for text in ["S_zz", "TH-1", "DH-1", "u_T = 0.2 K"] {
        assert!(cert.contains(text), "{text}");
    }

    // The thermometer found nonconforming: the model made with it is held.
    let nc = json!({"found_at": ago(DAY), "last_known_good_at": ago(100 * DAY),
        "reason": "Reads 0.8 K high below 0 °C."});
    let res = app
        .post("/v1/standards/TH-1/nonconformity", ADMIN, &nc)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let state = app
        .get_json(&format!("/v1/calibrations/{id}/signatures"), ADMIN)
        .await;
    assert_eq!(state["state"], "under_review", "{state}");
    let affected = app.get_json("/v1/standards/TH-1/affected", ADMIN).await;
    assert_eq!(
        affected["nonconformities"][0]["calibrations"][0]["calibration_id"], stored["id"],
        "{affected}"
    );
    // Reprocessing fits and judges the same model again.
    let again = crate::thermal_stored::reprocessed(&app, &id).await;
    assert_eq!(again["thermal"], stored["thermal"]);
    assert_eq!(again["decision"], stored["decision"]);
}

/// Fitted, not stored: the thermometer named enters the elements as it
/// does a stored model's; a sensor type is refused (it judges a model
/// when stored).
#[tokio::test]
async fn an_identified_triad_model_takes_its_thermometer() {
    let app = TestApp::spawn(Sqlite).await;
    let res = app
        .put(
            "/v1/standards/TH-1",
            ADMIN,
            &standard("thermometer", json!({"temperature_std_c": U_T})),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let mut b = body(&CHAMBER);
    b["standards"] = json!({"thermometer": "TH-1"});
    let r: Value = app
        .post("/v1/identify/thermal/triad", ADMIN, &b)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["thermometer_std_c"], U_T, "{r}");
    b["sensor_type"] = json!("IMU-THERM");
    let p = problem(
        app.post("/v1/identify/thermal/triad", ADMIN, &b).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/sensor_type"], "{p}");
}
