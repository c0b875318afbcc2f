//! A triad's temperature model from stored triad calibrations named by id
//! (issue 45 item 1, triads), on both engines: a triad at one temperature
//! keeps its runs' temperatures (their mean its `temperature_c`, every
//! reading within 0.5 K), and five such triads of one sensor, each tumbled
//! at its own chamber set point, make the model their runs sent whole in
//! one body make — to the last bit, computed here by sending that body —
//! stored with the ids it came from, performed when the last was, and
//! fitted again from them on reprocessing. Static positions combine
//! alike, and recordings by their static intervals (each set point then
//! the stored triad's own fit); every calibration that cannot take part is
//! refused naming it.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal::domain::timestamp::Timestamp;
use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

use crate::thermal_triad::{CHAMBER, body, f, refused};

fn ago(days: i64) -> String {
    Timestamp::now().plus_seconds(-days * 86_400).to_string()
}

/// `b` as triad `sensor`, performed `days` ago.
fn of(mut b: Value, sensor: &str, days: i64) -> Value {
    b["sensor_id"] = json!(sensor);
    b["performed_at"] = json!(ago(days));
    b
}

/// `b` stored as a triad at one temperature: its id and result.
async fn stored(app: &TestApp, b: &Value) -> (String, Value) {
    let r = app
        .expect(StatusCode::CREATED, "/v1/calibrations/triad", ADMIN, b)
        .await;
    (r["id"].as_str().unwrap().to_owned(), r)
}

/// The model `b` makes at `path`, answered 200.
async fn fitted(app: &TestApp, path: &str, b: &Value) -> Value {
    app.expect(StatusCode::OK, path, ADMIN, b).await
}

#[rstest]
#[tokio::test]
async fn a_model_from_stored_triads_is_the_model_of_their_runs(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let mut ids = Vec::new();
    let mut whole = body(&[]);
    whole["sensor_id"] = json!("IMU-C");
    for (s, &t) in CHAMBER.iter().enumerate() {
        let b = of(body(&[t]), "IMU-C", 5 - s as i64);
        let (id, r) = stored(&app, &b).await;
        // At one temperature: the mean of its ten runs' (within ±0.02 K).
        let runs = b["runs"].as_array().unwrap();
        let mean = runs.iter().map(|r| f(&r["temperature_c"])).sum::<f64>() / runs.len() as f64;
        assert!(
            (f(&r["temperature_c"]) - mean).abs() < 1e-12,
            "{}",
            r["temperature_c"]
        );
        ids.push(id);
        whole["runs"]
            .as_array_mut()
            .unwrap()
            .extend(runs.iter().cloned());
    }
    let whole_model = fitted(&app, "/v1/identify/thermal/triad", &whole).await;
    let named = json!({"sensor_id": "IMU-C", "calibrations": ids});
    let combined = fitted(&app, "/v1/identify/thermal/triad", &named).await;
    assert_eq!(combined, whole_model);
    assert_eq!(combined["set_points"].as_array().unwrap().len(), 5);

    let model = app
        .expect(
            StatusCode::CREATED,
            "/v1/calibrations/thermal/triad",
            ADMIN,
            &named,
        )
        .await;
    crate::conforms_to("StoredThermalTriad", &model);
    assert_eq!(model["thermal"], whole_model);
    assert_eq!(model["runs"], 50);
    let again =
        crate::thermal_combined::keeps_where_it_came_from(&app, &model, &named, &ids, &whole_model)
            .await;
    // A triad's page states its temperature.
    let (session, _) = crate::ui::sign_in(&app, ADMIN).await;
    let html = crate::ui::page(&app, &format!("/ui/calibrations/{}", ids[0]), &session)
        .await
        .text()
        .await
        .unwrap();
    assert!(
        html.contains("the readings' mean, all within 0.5 K"),
        "states its temperature"
    );
    // Its elements at T_ref are those of the model sent whole and stored.
    whole["sensor_id"] = json!("IMU-W");
    let stored_whole = app
        .expect(
            StatusCode::CREATED,
            "/v1/calibrations/thermal/triad",
            ADMIN,
            &whole,
        )
        .await;
    assert_eq!(stored_whole["elements"], again["elements"]);
}

#[tokio::test]
async fn static_positions_and_recordings_combine_by_their_positions() {
    use crate::thermal_triad_static::{body as positions, recording_of};
    let app = TestApp::spawn(Sqlite).await;
    // Static positions: the body of all their positions, to the last bit.
    let (mut ids, mut whole) = (Vec::new(), positions(&[]));
    whole["sensor_id"] = json!("IMU-P");
    for (s, &t) in crate::thermal_triad_static::CHAMBER.iter().enumerate() {
        let b = of(positions(&[t]), "IMU-P", 5 - s as i64);
        let (id, r) = stored(&app, &b).await;
        let ts = b["static_temperatures_c"].as_array().unwrap();
        let mean = ts.iter().map(f).sum::<f64>() / ts.len() as f64;
        assert!((f(&r["temperature_c"]) - mean).abs() < 1e-12);
        ids.push(id);
        for key in ["static_positions", "static_temperatures_c"] {
            let more = b[key].as_array().unwrap().clone();
            whole[key].as_array_mut().unwrap().extend(more);
        }
    }
    let named = json!({"sensor_id": "IMU-P", "calibrations": ids});
    let combined = fitted(&app, "/v1/identify/thermal/triad", &named).await;
    assert_eq!(
        combined,
        fitted(&app, "/v1/identify/thermal/triad", &whole).await
    );
    assert_eq!(combined["method"], "gravity_magnitude");

    // Recordings, one a set point: each set point is the fit of that
    // recording's static intervals, as the stored triad made it.
    let mut ids = Vec::new();
    let mut triads = Vec::new();
    for (s, &t) in [-20.0, 5.0, 30.0].iter().enumerate() {
        let (id, r) = stored(&app, &of(recording_of(&[t]), "IMU-Q", 3 - s as i64)).await;
        assert!(
            (f(&r["temperature_c"]) - t).abs() < 0.03,
            "{}",
            r["temperature_c"]
        );
        ids.push(id);
        triads.push(r);
    }
    let named = json!({"sensor_id": "IMU-Q", "calibrations": ids});
    let model = fitted(&app, "/v1/identify/thermal/triad", &named).await;
    let set_points = model["set_points"].as_array().unwrap();
    assert_eq!(set_points.len(), 3);
    for (sp, r) in set_points.iter().zip(&triads) {
        assert_eq!(sp["b"], r["b"]);
        assert_eq!(sp["b_std_errors"], r["b_std_errors"]);
        assert_eq!(sp["S"], r["S"]);
        assert_eq!(sp["S_std_errors"], r["S_std_errors"]);
        assert_eq!(sp["runs"].as_array().unwrap().len(), 14, "{}", sp["runs"]);
    }
    // Each element the weighted fit of its set points, holding the planted
    // value at T_ref.
    let reference = f(&model["b"][0]["reference_c"]);
    let (b, s) = crate::thermal_triad_static::planted(reference);
    for (m, n, want) in [
        (0, None, b[0]),
        (1, Some(1), s[1][1]),
        (2, Some(0), s[2][0]),
    ] {
        crate::thermal_triad::fits_its_set_points(&model, m, n, want);
    }
}

#[tokio::test]
async fn triads_that_cannot_make_a_model_are_refused_by_name() {
    let app = TestApp::spawn(Sqlite).await;
    let mut ids = Vec::new();
    for (s, &t) in CHAMBER.iter().enumerate() {
        ids.push(stored(&app, &of(body(&[t]), "IMU-R", 5 - s as i64)).await.0);
    }
    let mut untempered = of(body(&[25.0]), "IMU-R", 1);
    for run in untempered["runs"].as_array_mut().unwrap() {
        run.as_object_mut().unwrap().remove("temperature_c");
    }
    let untempered = stored(&app, &untempered).await.0;
    let mut square = of(body(&[-5.0]), "IMU-R", 1);
    square["second_order"] = json!(true);
    let square = stored(&app, &square).await.0;
    let mut milli = of(body(&[10.0]), "IMU-R", 1);
    milli["unit"] = json!("g");
    let milli = stored(&app, &milli).await.0;
    let cube = {
        let b = of(body(&[50.0]), "IMU-R", 1);
        let mut c = b.clone();
        // The same faces in another order: other orientations.
        for run in c["runs"].as_array_mut().unwrap() {
            run["samples"].as_array_mut().unwrap().swap(0, 1);
        }
        c["orientations"] = json!([
            [-1, 0, 0],
            [1, 0, 0],
            [0, 1, 0],
            [0, -1, 0],
            [0, 0, 1],
            [0, 0, -1]
        ]);
        stored(&app, &c).await.0
    };
    let still = stored(
        &app,
        &of(crate::thermal_triad_static::body(&[30.0]), "IMU-R", 1),
    )
    .await
    .0;
    let model = app
        .expect(
            StatusCode::CREATED,
            "/v1/calibrations/thermal/triad",
            ADMIN,
            &of(body(&CHAMBER), "IMU-R", 1),
        )
        .await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let single = app
        .submit(ADMIN, &{
            let mut b = crate::thermal::body(&[20.0]);
            b["sensor_id"] = json!("AXIS-1");
            b
        })
        .await["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let other = stored(&app, &of(body(&[20.0]), "IMU-O", 1)).await.0;
    let unknown = "01a22583-0000-7000-8000-000000000000";
    for (sensor, calibrations, pointer, says) in [
        (
            "IMU-R",
            json!([ids[0], unknown]),
            "/calibrations/1",
            "no calibration",
        ),
        (
            "IMU-R",
            json!([other, ids[0]]),
            "/calibrations/0",
            "of sensor `IMU-O`",
        ),
        (
            "AXIS-1",
            json!([single, single]),
            "/calibrations/1",
            "again",
        ),
        (
            "AXIS-1",
            json!([single, ids[0]]),
            "/calibrations/0",
            "a single axis's",
        ),
        (
            "IMU-R",
            json!([ids[0], model]),
            "/calibrations/1",
            "a temperature model",
        ),
        (
            "IMU-R",
            json!([ids[0], untempered]),
            "/calibrations/1",
            "carries no temperatures",
        ),
        (
            "IMU-R",
            json!([ids[0], square]),
            "/calibrations/1",
            "second-order",
        ),
        (
            "IMU-R",
            json!([ids[0], milli]),
            "/calibrations/1",
            "unit (g)",
        ),
        (
            "IMU-R",
            json!([ids[0], cube]),
            "/calibrations/1",
            "other orientations",
        ),
        (
            "IMU-R",
            json!([ids[0], still]),
            "/calibrations/1",
            "not of the first's method",
        ),
        ("IMU-R", json!([ids[0]]), "/calibrations", "2 to 64"),
    ] {
        let named = json!({"sensor_id": sensor, "calibrations": calibrations});
        let p = refused(&app, named, "/v1/calibrations/thermal/triad").await;
        assert_eq!(pointers(&p), [pointer], "{calibrations}: {p}");
        assert!(
            p["errors"][0]["detail"].as_str().unwrap().contains(says),
            "{calibrations}: {p}"
        );
    }
    // A single axis's model does not take triads.
    let p = refused(
        &app,
        json!({"sensor_id": "IMU-R", "calibrations": [ids[0], ids[1]]}),
        "/v1/calibrations/thermal",
    )
    .await;
    assert!(p.to_string().contains("a triad's"), "{p}");
    // Set points too close together: the fit's own refusal.
    let near = stored(&app, &of(body(&[-15.0]), "IMU-R", 1)).await.0;
    let p = refused(
        &app,
        json!({"sensor_id": "IMU-R", "calibrations": [ids[0], near]}),
        "/v1/identify/thermal/triad",
    )
    .await;
    assert!(p.to_string().contains("less than the 10 K"), "{p}");
}

/// A triad at one temperature holds its readings within 0.5 K: the
/// hottest beyond is refused where it is, for each form.
#[tokio::test]
async fn a_triad_at_one_temperature_is_held_within_the_tolerance() {
    let app = TestApp::spawn(Sqlite).await;
    let path = "/v1/calibrations/triad";
    let mut b = of(body(&[20.0]), "IMU-H", 1);
    let base = f(&b["runs"][0]["temperature_c"]);
    // 0.45 K above the coolest of ±0.02 K: within at most 0.47 K.
    b["runs"][6]["temperature_c"] = json!(20.45);
    let (_, r) = stored(&app, &b).await;
    assert!(f(&r["temperature_c"]) > 20.0, "{r}");
    b["runs"][6]["temperature_c"] = json!(base + 0.7);
    let p = refused(&app, b.clone(), path).await;
    assert_eq!(pointers(&p), ["/runs/6/temperature_c"], "{p}");
    assert!(p.to_string().contains("0.5 K"), "{p}");
    // One per position: the run's mean may lie within while a position does not.
    b["runs"][6]["temperature_c"] = json!([base, base, base, base, base, base + 0.7]);
    let p = refused(&app, b, path).await;
    assert_eq!(pointers(&p), ["/runs/6/temperature_c"], "{p}");

    let mut s = of(crate::thermal_triad_static::body(&[20.0]), "IMU-H", 1);
    s["static_temperatures_c"][11] = json!(21.0);
    let p = refused(&app, s, path).await;
    assert_eq!(pointers(&p), ["/static_temperatures_c/11"], "{p}");
    // The coolest is named when it is the odd one out.
    let mut rec = of(
        crate::thermal_triad_static::recording_of(&[20.0]),
        "IMU-H",
        1,
    );
    rec["recording"]["temperature_c"][300] = json!(19.0);
    let p = refused(&app, rec, path).await;
    assert_eq!(pointers(&p), ["/recording/temperature_c/300"], "{p}");
}

/// Triads held under review by a nonconformity of the thermometer they
/// used are refused by name: a model fitted from them would not be held.
/// Approved again, they make one, which records the thermometer.
#[tokio::test]
async fn triads_held_under_review_are_refused_until_approved_again() {
    use crate::thermal_standards::{DAY, ago, stand_and_thermometer};
    let app = TestApp::spawn(Sqlite).await;
    stand_and_thermometer(&app, 0.2).await;
    let mut ids = Vec::new();
    for (s, &t) in CHAMBER.iter().enumerate() {
        let mut b = body(&[t]);
        b["sensor_id"] = json!("IMU-N");
        b["performed_at"] = json!(ago((40 - s as i64) * DAY));
        b["standards"] = json!({"thermometer": "TH-1"});
        ids.push(stored(&app, &b).await.0);
    }
    let nc = json!({"found_at": ago(DAY), "last_known_good_at": ago(100 * DAY),
        "reason": "Reads 0.8 K high below 0 °C."});
    app.expect(
        StatusCode::CREATED,
        "/v1/standards/TH-1/nonconformity",
        ADMIN,
        &nc,
    )
    .await;
    let named = json!({"sensor_id": "IMU-N", "calibrations": ids});
    let p = refused(&app, named.clone(), "/v1/calibrations/thermal/triad").await;
    assert_eq!(pointers(&p), ["/calibrations/0"], "{p}");
    assert!(p.to_string().contains("is under review"), "{p}");
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    for id in &ids {
        app.expect(
            StatusCode::OK,
            &format!("/v1/calibrations/{id}/review"),
            &rita,
            &json!({"decision": "approve", "comment": "below 0 °C corrected by the lab"}),
        )
        .await;
    }
    let model = app
        .expect(
            StatusCode::CREATED,
            "/v1/calibrations/thermal/triad",
            ADMIN,
            &named,
        )
        .await;
    assert_eq!(
        model["standards"][0]["standard_id"], "TH-1",
        "{}",
        model["standards"]
    );
    assert_eq!(model["thermal"]["thermometer_std_c"], 0.2);
    // None of them can stop counting while the model counts.
    let res = app
        .post(
            &format!("/v1/calibrations/{}/withdraw", ids[4]),
            &rita,
            &json!({"reason": "wrong sensor"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CONFLICT);
    let p: Value = res.json().await.unwrap();
    let id = model["id"].as_str().unwrap();
    assert!(p["detail"].as_str().unwrap().contains(id), "{p}");
}
