//! A temperature model from stored calibrations named by id (issue 45
//! item 1), on both engines: five single-axis calibrations of one sensor,
//! each tumbled at its own chamber set point, make the model that their
//! runs sent whole in one body make — the same set points and polynomials
//! to the last bit, computed here by sending that body — stored with the
//! ids it came from, performed when the last was, and fitted again from
//! them on reprocessing; every calibration that cannot take part is
//! refused naming it.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal::domain::timestamp::Timestamp;
use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

use crate::thermal::{CHAMBER, body};

fn ago(days: i64) -> String {
    Timestamp::now().plus_seconds(-days * 86_400).to_string()
}

/// The single-axis body of `sensor` at set point `t`, performed `days` ago.
fn at(sensor: &str, t: f64, days: i64) -> Value {
    let mut b = body(&[t]);
    b["sensor_id"] = json!(sensor);
    b["performed_at"] = json!(ago(days));
    b
}

/// The model of `sensor` fitted from the stored calibrations `ids`, stored.
async fn fitted_from(app: &TestApp, sensor: &str, ids: &[String]) -> Value {
    let named = json!({"sensor_id": sensor, "calibrations": ids});
    app.expect(
        StatusCode::CREATED,
        "/v1/calibrations/thermal",
        ADMIN,
        &named,
    )
    .await
}

/// Calibration `id`'s record of signatures, with its state.
async fn signatures(app: &TestApp, id: &str) -> Value {
    app.get_json(&format!("/v1/calibrations/{id}/signatures"), ADMIN)
        .await
}

#[rstest]
#[tokio::test]
async fn a_model_from_stored_calibrations_is_the_model_of_their_runs(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let mut ids = Vec::new();
    let mut whole = body(&[]);
    whole["sensor_id"] = json!("MEMS-C");
    for (s, &t) in CHAMBER.iter().enumerate() {
        let b = at("MEMS-C", t, 5 - s as i64);
        let stored = app.submit(ADMIN, &b).await;
        ids.push(stored["id"].as_str().unwrap().to_owned());
        for run in b["runs"].as_array().unwrap() {
            whole["runs"].as_array_mut().unwrap().push(run.clone());
        }
    }
    let whole_model: Value = app
        .post("/v1/identify/thermal", ADMIN, &whole)
        .await
        .json()
        .await
        .unwrap();
    let named = json!({"sensor_id": "MEMS-C", "calibrations": ids});
    let res = app.post("/v1/identify/thermal", ADMIN, &named).await;
    assert_eq!(res.status(), StatusCode::OK);
    let combined: Value = res.json().await.unwrap();
    assert_eq!(combined, whole_model);
    assert_eq!(combined["set_points"].as_array().unwrap().len(), 5);

    let res = app.post("/v1/calibrations/thermal", ADMIN, &named).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let stored: Value = res.json().await.unwrap();
    crate::conforms_to("StoredThermal", &stored);
    assert_eq!(stored["thermal"], whole_model);
    assert_eq!(stored["runs"], 40);
    keeps_where_it_came_from(&app, &stored, &named, &ids, &whole_model).await;
}

/// The stored model `model` fitted from the calibrations `ids`, which the
/// body `named` named, keeps them: it lists them, is performed when the
/// last of them was, stores the body sent, fits `whole_model` again from
/// them on reprocessing (returned) and links each from its page.
pub(crate) async fn keeps_where_it_came_from(
    app: &TestApp,
    model: &Value,
    named: &Value,
    ids: &[String],
    whole_model: &Value,
) -> Value {
    assert_eq!(model["from_calibrations"], json!(ids));
    let last = app
        .get_json(&format!("/v1/calibrations/{}", ids[ids.len() - 1]), ADMIN)
        .await;
    assert_eq!(model["performed_at"], last["performed_at"]);
    let id = model["id"].as_str().unwrap();
    let res = app
        .get(&format!("/v1/calibrations/{id}/submission"), ADMIN)
        .await;
    assert_eq!(&res.json::<Value>().await.unwrap(), named);
    let again = crate::thermal_stored::reprocessed(app, id).await;
    assert_eq!(&again["thermal"], whole_model);
    let (session, _) = crate::ui::sign_in(app, ADMIN).await;
    let html = crate::ui::page(app, &format!("/ui/calibrations/{id}"), &session)
        .await
        .text()
        .await
        .unwrap();
    for c in ids {
        assert!(html.contains(&format!("/ui/calibrations/{c}")), "links {c}");
    }
    again
}

/// A nonconformity found after a model was fitted holds the model when it
/// holds a calibration the model was fitted from, though its window ends
/// before the model was performed (when its last calibration was, made
/// with another thermometer): the trace follows `from_calibrations`. A
/// model fitted only from calibrations it does not hold is left.
#[rstest]
#[tokio::test]
async fn a_nonconformity_found_later_holds_the_models_fitted_from_what_it_holds(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    crate::thermal_standards::stand_and_thermometer(&app, 0.2).await;
    let th2 = crate::thermal_standards::standard("thermometer", json!({"temperature_std_c": 0.1}));
    let res = app.put("/v1/standards/TH-2", ADMIN, &th2).await;
    assert_eq!(
        res.status(),
        StatusCode::CREATED,
        "{}",
        res.text().await.unwrap()
    );
    // MEMS-H: the two coolest set points with TH-1 (50 and 40 days ago),
    // the rest with TH-2 (30, 20, 10 days ago); MEMS-K: all with TH-2.
    let mut models = Vec::new();
    let mut held_constituents = Vec::new();
    for sensor in ["MEMS-H", "MEMS-K"] {
        let mut ids = Vec::new();
        for (s, &t) in CHAMBER.iter().enumerate() {
            let mut b = at(sensor, t, 50 - 10 * s as i64);
            let th = if sensor == "MEMS-H" && s < 2 {
                "TH-1"
            } else {
                "TH-2"
            };
            b["standards"] = json!({"stand": "DH-1", "thermometer": th});
            ids.push(
                app.submit(ADMIN, &b).await["id"]
                    .as_str()
                    .unwrap()
                    .to_owned(),
            );
        }
        if sensor == "MEMS-H" {
            held_constituents = ids[..2].to_vec();
        }
        let model = fitted_from(&app, sensor, &ids).await;
        let used = model["standards"].as_array().unwrap().len();
        assert_eq!(used, if sensor == "MEMS-H" { 3 } else { 2 });
        models.push(model["id"].as_str().unwrap().to_owned());
    }
    // TH-1 found reading high 35 days ago: its window ends before MEMS-H's
    // third calibration, and before its model was performed (10 days ago).
    let nc = json!({"found_at": ago(35), "last_known_good_at": ago(100),
        "reason": "Reads 0.8 K high below 0 °C."});
    let traced = app
        .expect(
            StatusCode::CREATED,
            "/v1/standards/TH-1/nonconformity",
            ADMIN,
            &nc,
        )
        .await;
    let mut listed: Vec<(String, String)> = traced["calibrations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let id = c["calibration_id"].as_str().unwrap().to_owned();
            (id, c["state"].as_str().unwrap().to_owned())
        })
        .collect();
    listed.sort();
    let mut expected: Vec<(String, String)> = held_constituents
        .iter()
        .chain(&models[..1])
        .map(|id| (id.clone(), "under_review".to_owned()))
        .collect();
    expected.sort();
    assert_eq!(listed, expected);
    assert_eq!(signatures(&app, &models[0]).await["state"], "under_review");
    assert_eq!(signatures(&app, &models[1]).await["state"], "submitted");
}

/// A calibration a temperature model was fitted from cannot stop counting
/// while the model counts: rejecting, withdrawing or superseding it is a
/// 409 naming the model (which would stand on a measurement that no
/// longer counts), and nothing is signed; once the model is withdrawn the
/// calibration can be rejected. Holding it under review is not refused.
#[rstest]
#[tokio::test]
async fn a_calibration_a_model_was_fitted_from_stops_counting_only_after_the_model(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let mut ids = Vec::new();
    for (s, &t) in CHAMBER.iter().enumerate() {
        let b = at("MEMS-R", t, 5 - s as i64);
        ids.push(
            app.submit(ADMIN, &b).await["id"]
                .as_str()
                .unwrap()
                .to_owned(),
        );
    }
    let model = fitted_from(&app, "MEMS-R", &ids).await;
    let model = model["id"].as_str().unwrap().to_owned();
    let c = &ids[2];
    let mut replacement = at("MEMS-R", CHAMBER[2], 5 - 2);
    replacement["station_id"] = json!("CHAMBER-2");
    for (path, token, body) in [
        (
            format!("/v1/calibrations/{c}/review"),
            &rita,
            json!({"decision": "reject", "comment": "chamber door left open"}),
        ),
        (
            format!("/v1/calibrations/{c}/withdraw"),
            &rita,
            json!({"reason": "wrong sensor"}),
        ),
        (
            format!("/v1/calibrations/{c}/supersede?reason=station%20id"),
            &rita,
            replacement,
        ),
    ] {
        let res = app.post(&path, token, &body).await;
        assert_eq!(res.status(), StatusCode::CONFLICT, "{path}");
        let p: Value = res.json().await.unwrap();
        assert!(p["detail"].as_str().unwrap().contains(&model), "{p}");
    }
    let s = signatures(&app, c).await;
    assert_eq!(s["state"], "submitted", "{s}");
    assert_eq!(s["signatures"].as_array().unwrap().len(), 0, "{s}");
    // The model withdrawn, the calibration can be rejected.
    app.expect(
        StatusCode::OK,
        &format!("/v1/calibrations/{model}/withdraw"),
        &rita,
        &json!({"reason": "refitted without the 20 °C point"}),
    )
    .await;
    app.expect(
        StatusCode::OK,
        &format!("/v1/calibrations/{c}/review"),
        &rita,
        &json!({"decision": "reject", "comment": "chamber door left open"}),
    )
    .await;
    assert_eq!(signatures(&app, c).await["state"], "rejected");
}

#[tokio::test]
async fn calibrations_that_cannot_make_a_model_are_refused_by_name() {
    let app = TestApp::spawn(Sqlite).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let mut ids = Vec::new();
    for (s, &t) in CHAMBER.iter().enumerate() {
        let stored = app.submit(ADMIN, &at("MEMS-R", t, 5 - s as i64)).await;
        ids.push(stored["id"].as_str().unwrap().to_owned());
    }
    let other = app.submit(ADMIN, &at("OTHER", 20.0, 1)).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let mut milliamps = at("MEMS-R", 25.0, 1);
    milliamps["unit"] = json!("mA");
    let milliamps = app.submit(ADMIN, &milliamps).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let mut cold = at("MEMS-R", -5.0, 1);
    for run in cold["runs"].as_array_mut().unwrap() {
        run.as_object_mut().unwrap().remove("temperature_c");
    }
    let cold = app.submit(ADMIN, &cold).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let res = app
        .post(
            &format!("/v1/calibrations/{}/review", ids[2]),
            &rita,
            &json!({"decision": "reject", "comment": "chamber door open"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);

    let refused = |calibrations: Value| {
        let app = &app;
        async move {
            let named = json!({"sensor_id": "MEMS-R", "calibrations": calibrations});
            problem(
                app.post("/v1/calibrations/thermal", ADMIN, &named).await,
                StatusCode::UNPROCESSABLE_ENTITY,
            )
            .await
        }
    };
    let unknown = "01a22583-0000-7000-8000-000000000000";
    for (calibrations, pointer, says) in [
        (
            json!([ids[0], unknown]),
            "/calibrations/1",
            "no calibration",
        ),
        (
            json!([other, ids[0]]),
            "/calibrations/0",
            "of sensor `OTHER`",
        ),
        (json!([ids[0], ids[0]]), "/calibrations/1", "again"),
        (json!([ids[0], "x"]), "/calibrations/1", "a UUID"),
        (json!([ids[0]]), "/calibrations", "2 to 64"),
        (json!([ids[0], ids[2]]), "/calibrations/1", "is rejected"),
        (json!([ids[0], milliamps]), "/calibrations/1", "unit (mA)"),
        (json!([ids[0], cold]), "/calibrations/1", "no temperature_c"),
    ] {
        let p = refused(calibrations.clone()).await;
        assert_eq!(pointers(&p), [pointer], "{calibrations}: {p}");
        assert!(
            p["errors"][0]["detail"].as_str().unwrap().contains(says),
            "{calibrations}: {p}"
        );
    }
    // Set points too close together: the fit's own refusal.
    let near = app.submit(ADMIN, &at("MEMS-R", -15.0, 1)).await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let p = refused(json!([ids[0], near])).await;
    assert!(p.to_string().contains("less than the 10 K"), "{p}");
    // An unknown member is named.
    let p = problem(
        app.post(
            "/v1/calibrations/thermal",
            ADMIN,
            &json!({"sensor_id": "MEMS-R", "calibrations": [ids[0], ids[1]], "runs": []}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/runs"], "{p}");
    // Nothing was stored for the sensor but its calibrations.
    let history = app.get_json("/v1/sensors/MEMS-R/calibrations", ADMIN).await;
    assert_eq!(history["items"].as_array().unwrap().len(), 8, "{history}");
}
