//! Stored triads (issue 30): `POST /v1/calibrations/triad` stores what
//! `POST /v1/identify/triad` computes, bit for bit; the calibration reads
//! back through every read (result, sensor, history, coefficients);
//! compensation with triples inverts the stored `b` and `S`; the exports
//! carry the stored elements; stability is judged element by element; and
//! single-axis and triad calibrations never mix on one sensor.

use reqwest::StatusCode;
use reqwest::header::{CONTENT_TYPE, LOCATION};
use rstest::rstest;
use serde_json::{Value, json};

use super::triad::{f, faces, gravity_positions, known_body, lower_s, positions_at};
use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

/// Stores `body` as a triad; the answer, expecting 201.
async fn store(app: &TestApp, token: &str, body: &Value) -> Value {
    let res = app.post("/v1/calibrations/triad", token, body).await;
    let status = res.status();
    let location = res.headers().get(LOCATION).cloned();
    let text = res.text().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{text}");
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(
        location.unwrap().to_str().unwrap(),
        format!("/v1/calibrations/{}", v["id"].as_str().unwrap())
    );
    v
}

fn vector(v: &Value) -> [f64; 3] {
    [0, 1, 2].map(|m| f(&v[m]))
}

fn matrix(v: &Value) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|m| vector(&v[m]))
}

/// Stores, as CSV static positions under the `meta` lines, a diagonal
/// triad's outputs `b_m + scale_m · d_m` at ten directions spanning the
/// sphere (the six faces and four oblique ones).
async fn post_static_csv(
    app: &TestApp,
    meta: &str,
    b: [f64; 3],
    scale: [f64; 3],
) -> reqwest::Response {
    let mut csv = format!("{meta}position,u_x,u_y,u_z\n");
    let mut dirs = faces();
    dirs.extend([
        [0.6, 0.8, 0.0],
        [0.0, 0.6, 0.8],
        [0.8, 0.0, 0.6],
        [-0.48, 0.6, 0.64],
    ]);
    for (p, d) in dirs.iter().enumerate() {
        let u = [0, 1, 2].map(|m| b[m] + scale[m] * d[m]);
        csv.push_str(&format!("{p},{},{},{}\n", u[0], u[1], u[2]));
    }
    app.client
        .post(app.url("/v1/calibrations/triad"))
        .bearer_auth(ADMIN)
        .header(CONTENT_TYPE, "text/csv")
        .body(csv)
        .send()
        .await
        .unwrap()
}

/// A 3×3 inverse by cofactors (independent of the service's).
fn inverse(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let c = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
    };
    let det: f64 = (0..3).map(|j| m[0][j] * c(0, j)).sum();
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| c(j, i) / det))
}

#[rstest]
#[tokio::test]
async fn a_stored_triad_reads_back_compensates_and_exports(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let station = app.token("station", Some("LAB-3")).await;
    let mut body = known_body();
    body["performed_at"] = json!("2026-10-01T08:00:00Z");
    let computed: Value = app
        .post("/v1/identify/triad", ADMIN, &body)
        .await
        .json()
        .await
        .unwrap();
    let stored = store(&app, &station, &body).await;
    let id = stored["id"].as_str().unwrap().to_owned();
    // What is stored is what is computed, bit for bit, with the record's
    // own fields: the station comes from the bound token.
    for key in [
        "b",
        "S",
        "T",
        "b_std_errors",
        "S_std_errors",
        "scale_factors",
        "residuals",
    ] {
        assert_eq!(stored[key], computed[key], "{key}");
    }
    assert_eq!(stored["station_id"], "LAB-3");
    assert_eq!(stored["performed_at"], "2026-10-01T08:00:00.000000Z");
    assert_eq!(stored["sensor_id"], "IMU-7");
    assert_eq!(
        app.get_json(&format!("/v1/calibrations/{id}"), ADMIN).await,
        stored
    );

    // The sensor, its history and its coefficients carry the elements.
    let sensor = app.get_json("/v1/sensors/IMU-7", ADMIN).await;
    let latest = &sensor["latest"];
    assert_eq!(latest["id"], id.as_str());
    assert_eq!(latest["model"], json!(["k0", "ki", "kp", "ko"]));
    assert_eq!(latest["coefficients"], json!({}));
    assert_eq!(latest["runs"], 6);
    for key in ["b", "S", "T", "b_std_errors", "S_std_errors"] {
        assert_eq!(latest["triad"][key], stored[key], "{key}");
    }
    assert_eq!(latest["triad"]["method"], "known_orientations");
    assert_eq!(latest["triad"]["T_std_errors"], Value::Null);
    let history = app.get_json("/v1/sensors/IMU-7/calibrations", ADMIN).await;
    assert_eq!(history["items"][0]["triad"], latest["triad"]);
    let coefficients = app.get_json("/v1/sensors/IMU-7/coefficients", ADMIN).await;
    assert_eq!(coefficients["triad"], latest["triad"]);

    // Compensation inverts u = b + S g: outputs made in the test from the
    // stored b and S give their g back.
    let (b, s) = (vector(&stored["b"]), matrix(&stored["S"]));
    let gs = [
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.6, 0.0, 0.8],
        [0.3, -0.4, 0.2],
    ];
    let outputs: Vec<[f64; 3]> = gs
        .iter()
        .map(|g| [0, 1, 2].map(|m| b[m] + (0..3).map(|k| s[m][k] * g[k]).sum::<f64>()))
        .collect();
    let res = app
        .post(
            "/v1/sensors/IMU-7/compensate",
            ADMIN,
            &json!({ "outputs": outputs }),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let c: Value = res.json().await.unwrap();
    assert_eq!(c["calibration_id"], id.as_str());
    assert_eq!(c["usable"], true);
    assert_eq!(c["unit"], "m/s2");
    assert!(c.get("a_i").is_none(), "{c}");
    for (k, g) in gs.iter().enumerate() {
        for m in 0..3 {
            assert!((f(&c["g"][k][m]) - g[m]).abs() < 1e-12, "g{k}{m}: {c}");
        }
    }

    // The exports carry the stored elements.
    let export = |format: &str| {
        let app = &app;
        let url = format!("/v1/calibrations/{id}/export?format={format}");
        async move { app.get(&url, ADMIN).await }
    };
    let json_file: Value = export("json").await.json().await.unwrap();
    for key in ["b", "S", "T"] {
        assert_eq!(json_file[key], stored[key], "{key}");
    }
    assert!(json_file["source"].as_str().unwrap().contains(&id));
    let res = export("px4").await;
    assert_eq!(res.status(), StatusCode::OK);
    assert!(
        res.headers()["content-disposition"]
            .to_str()
            .unwrap()
            .contains("accelcal-px4.params")
    );
    let px4 = res.text().await.unwrap();
    let t = matrix(&stored["T"]);
    let param = |name: &str| -> f64 {
        let line = px4.lines().find(|l| l.contains(name)).unwrap();
        line.split('\t').nth(3).unwrap().parse().unwrap()
    };
    // PX4: a = (u − offset) ⊙ scale in m/s², offsets b, scales g₀·T_mm.
    for (m, axis) in ["X", "Y", "Z"].iter().enumerate() {
        let off = param(&format!("CAL_ACC0_{axis}OFF"));
        assert!((off - b[m]).abs() < 1e-8 * b[m].abs().max(1.0), "{axis}OFF");
        let scale = param(&format!("CAL_ACC0_{axis}SCALE"));
        assert!((scale - 9.80665 * t[m][m]).abs() < 1e-8, "{axis}SCALE");
    }
    let header = export("c").await.text().await.unwrap();
    assert!(header.contains("ACCELCAL_T[3][3]"), "{header}");
}

#[tokio::test]
async fn stability_is_judged_element_by_element() {
    let app = TestApp::spawn(Sqlite).await;
    let mut first = known_body();
    first["performed_at"] = json!("2025-10-01T00:00:00Z");
    let mut second = known_body();
    second["performed_at"] = json!("2026-10-01T00:00:00Z");
    // The second year's bias moved by 0.05 m/s² on every axis.
    for run in second["runs"].as_array_mut().unwrap() {
        for position in run["samples"].as_array_mut().unwrap() {
            for sample in position.as_array_mut().unwrap() {
                for u in sample.as_array_mut().unwrap() {
                    *u = json!(f(u) + 0.05);
                }
            }
        }
    }
    let a = store(&app, ADMIN, &first).await;
    let b = store(&app, ADMIN, &second).await;
    let report = app.get_json("/v1/sensors/IMU-7/stability", ADMIN).await;
    assert_eq!(report["calibrations"], 2);
    assert_eq!(report["terms"], json!({}));
    let elements = report["elements"].as_object().unwrap();
    assert_eq!(elements.len(), 21, "b, S and T");
    for (m, axis) in ["x", "y", "z"].iter().enumerate() {
        let e = &elements[&format!("b_{axis}")];
        let (x0, x1) = (f(&a["b"][m]), f(&b["b"][m]));
        assert!((f(&e["mean"]) - (x0 + x1) / 2.0).abs() < 1e-12);
        assert!((f(&e["latest_change"]) - (x1 - x0)).abs() < 1e-12);
        let (s0, s1) = (f(&a["b_std_errors"][m]), f(&b["b_std_errors"][m]));
        let expanded = 2.0 * (s0 * s0 + s1 * s1).sqrt();
        assert!((f(&e["latest_change_expanded"]) - expanded).abs() < 1e-15);
        assert_eq!(
            e["latest_change_significant"],
            json!((x1 - x0).abs() > expanded)
        );
        assert!((x1 - x0 - 0.05).abs() < 1e-9, "the planted change");
    }
    // As found: the second test's position means (its model plus its
    // residuals) compensated with the first's b and S, against the faces.
    let (b1, s1) = (vector(&a["b"]), matrix(&a["S"]));
    let inv = inverse(s1);
    let (b2, s2) = (vector(&b["b"]), matrix(&b["S"]));
    let found = &b["as_found"];
    assert_eq!(found["previous_calibration_id"], a["id"]);
    let mut largest = 0.0_f64;
    for (p, g) in faces().iter().enumerate() {
        let u: Vec<f64> = (0..3)
            .map(|m| {
                b2[m] + (0..3).map(|k| s2[m][k] * g[k]).sum::<f64>() + f(&b["residuals"][p][m])
            })
            .collect();
        for m in 0..3 {
            let e = (0..3).map(|k| inv[m][k] * (u[k] - b1[k])).sum::<f64>() - g[m];
            assert!(
                (f(&found["positions"][p][m]) - e).abs() < 1e-12,
                "position {p} axis {m}"
            );
            largest = largest.max(e.abs());
        }
    }
    assert!((f(&found["max_abs_error_g"]) - largest).abs() < 1e-12);
    assert!(
        (largest - 0.05 / 9.79).abs() < 1e-3,
        "the planted bias, in g: {largest}"
    );
    assert!(a.get("as_found").is_none(), "the first has none");
    // T has no standard errors from known orientations: its change is not judged.
    assert_eq!(elements["T_xx"]["latest_change_expanded"], Value::Null);
    assert!(elements["S_yz"]["latest_change_expanded"].is_number());

    // The sensor's page charts every element of b and S over time: each
    // chart's table has both calibrations, newest first, with the stored
    // value and its expanded uncertainty as the error bar.
    let (session, _) = super::ui::sign_in(&app, ADMIN).await;
    let page = super::ui::page(&app, "/ui/sensors/IMU-7", &session)
        .await
        .text()
        .await
        .unwrap();
    let mut charted = Vec::new();
    for (m, row) in ["x", "y", "z"].iter().enumerate() {
        charted.push((
            format!("b_{row}"),
            [&a, &b].map(|c| (f(&c["b"][m]), f(&c["b_expanded"][m]))),
        ));
        for (k, column) in ["x", "y", "z"].iter().enumerate() {
            charted.push((
                format!("S_{row}{column}"),
                [&a, &b].map(|c| (f(&c["S"][m][k]), f(&c["S_expanded"][m][k]))),
            ));
        }
    }
    for (name, values) in &charted {
        assert!(
            page.contains(&format!("id=\"chart-{name}\"")),
            "a chart of {name}"
        );
        let start = page
            .find(&format!("<table class=\"cards\" data-term=\"{name}\""))
            .unwrap_or_else(|| panic!("a table of {name}"));
        let table = &page[start..start + page[start..].find("</table>").unwrap()];
        let rows: Vec<&str> = table.split("<tr data-calibration-id=").skip(1).collect();
        assert_eq!(rows.len(), 2, "{name}");
        for (row, (c, (v, _))) in rows.iter().zip([(&b, values[1]), (&a, values[0])]) {
            assert!(
                row.starts_with(&format!("\"{}\"", c["id"].as_str().unwrap())),
                "{name}: newest first"
            );
            assert!(
                row.contains(&format!("data-value=\"{v}\"")),
                "{name}: {row}"
            );
            assert!(row.contains(" (U)"), "{name}: the expanded uncertainty");
        }
    }
    assert!(
        !page.contains("id=\"chart-T_xx\""),
        "T is derived: tabled, not charted"
    );
    assert!(
        page.contains("<tr data-term=\"T_xx\""),
        "T's stability is tabled"
    );
}

#[rstest]
#[tokio::test]
async fn single_axis_and_triad_calibrations_do_not_mix(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let triad = store(&app, ADMIN, &known_body()).await;
    let id = triad["id"].as_str().unwrap().to_owned();
    let single = app
        .submit(ADMIN, &submission("AXIS-1", "2026-01-01T00:00:00Z", 4))
        .await;
    let single_id = single["id"].as_str().unwrap().to_owned();

    // A single-axis submission for the triad, and a triad for the single axis.
    let p = problem(
        app.post(
            "/v1/calibrations",
            ADMIN,
            &submission("IMU-7", "2026-01-01T00:00:00Z", 4),
        )
        .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert!(p["type"].as_str().unwrap().ends_with("wrong-kind"), "{p}");
    assert_eq!(pointers(&p), ["/sensor_id"]);
    let mut body = known_body();
    body["sensor_id"] = json!("AXIS-1");
    let p = problem(
        app.post("/v1/calibrations/triad", ADMIN, &body).await,
        StatusCode::CONFLICT,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("single-axis"), "{p}");
    // A calibration is superseded by a submission of its own kind.
    let p = problem(
        app.post(
            &format!("/v1/calibrations/{id}/supersede?reason=x"),
            ADMIN,
            &submission("IMU-7", "2026-01-01T00:00:00Z", 4),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(p.to_string().contains("positions"), "{p}");
    let p = problem(
        app.post(
            &format!("/v1/calibrations/{single_id}/supersede?reason=x"),
            ADMIN,
            &known_body(),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(p.to_string().contains("orientations"), "{p}");
    for sensor in ["IMU-7", "AXIS-1"] {
        let history = app
            .get_json(&format!("/v1/sensors/{sensor}/calibrations"), ADMIN)
            .await;
        assert_eq!(
            history["items"].as_array().unwrap().len(),
            1,
            "nothing stored"
        );
    }
    // Exports are for triads.
    let p = problem(
        app.get(
            &format!("/v1/calibrations/{single_id}/export?format=json"),
            ADMIN,
        )
        .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert!(p["type"].as_str().unwrap().ends_with("wrong-kind"), "{p}");
    // Outputs of the wrong shape for the sensor.
    let p = problem(
        app.post(
            "/v1/sensors/IMU-7/compensate",
            ADMIN,
            &json!({"outputs": [1.0, 2.0]}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/outputs"]);
    let p = problem(
        app.post(
            "/v1/sensors/AXIS-1/compensate",
            ADMIN,
            &json!({"outputs": [[1.0, 2.0, 3.0]]}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/outputs"]);
    for (outputs, pointer) in [
        (json!([1.0, [1.0, 2.0, 3.0]]), "/outputs"),
        (json!([[1.0, 2.0]]), "/outputs/0"),
        (json!([[1.0, 2.0, 3.0, 4.0]]), "/outputs/0"),
        (json!([[1.0, "2", 3.0]]), "/outputs/0/1"),
    ] {
        let p = problem(
            app.post(
                "/v1/sensors/IMU-7/compensate",
                ADMIN,
                &json!({ "outputs": outputs }),
            )
            .await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(pointers(&p), [pointer], "{outputs}: {p}");
    }
    let p = problem(
        app.post(
            "/v1/sensors/IMU-7/compensate",
            ADMIN,
            &json!({"outputs": [[1.0, 2.0, 3.0]], "a_p": [0.1]}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/a_p"]);
}

#[tokio::test]
async fn each_refusal_of_a_stored_triad_names_its_field() {
    let app = TestApp::spawn(Sqlite).await;
    let reader = app.token("reader", None).await;
    let station = app.token("station", Some("LAB-3")).await;
    let res = app
        .post("/v1/calibrations/triad", &reader, &known_body())
        .await;
    assert_eq!(res.status(), StatusCode::FORBIDDEN);
    for (change, pointer) in [
        (json!({"sensor_id": null}), "/sensor_id"),
        (json!({"sensor_id": "IMU 7"}), "/sensor_id"),
        (
            json!({"performed_at": "2999-01-01T00:00:00Z"}),
            "/performed_at",
        ),
        (json!({"performed_at": "yesterday"}), "/performed_at"),
        (json!({"station_id": "../x"}), "/station_id"),
    ] {
        let mut body = known_body();
        for (k, v) in change.as_object().unwrap() {
            body[k] = v.clone();
        }
        let p = problem(
            app.post("/v1/calibrations/triad", ADMIN, &body).await,
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(pointers(&p), [pointer], "{change}: {p}");
    }
    // A station-bound token cannot act as another station.
    let mut body = known_body();
    body["station_id"] = json!("LAB-9");
    let res = app.post("/v1/calibrations/triad", &station, &body).await;
    assert_eq!(res.status(), StatusCode::FORBIDDEN);
    assert!(
        app.get("/v1/sensors/IMU-7", ADMIN).await.status() == StatusCode::NOT_FOUND,
        "nothing stored"
    );
    // Export: an unknown format, an unknown calibration, one that no longer counts.
    let stored = store(&app, ADMIN, &known_body()).await;
    let id = stored["id"].as_str().unwrap();
    let p = problem(
        app.get(&format!("/v1/calibrations/{id}/export?format=xls"), ADMIN)
            .await,
        StatusCode::BAD_REQUEST,
    )
    .await;
    assert_eq!(p["parameter"], "format", "{p}");
    let unknown = "01900000-0000-7000-8000-000000000000";
    let res = app
        .get(
            &format!("/v1/calibrations/{unknown}/export?format=c"),
            ADMIN,
        )
        .await;
    assert_eq!(res.status(), StatusCode::NOT_FOUND);
    let reviewer = app.held_token("reviewer", "Rita", None).await;
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/withdraw"),
            &reviewer,
            &json!({"reason": "the fixture slipped"}),
        )
        .await;
    assert_eq!(
        res.status(),
        StatusCode::OK,
        "{}",
        res.text().await.unwrap()
    );
    let p = problem(
        app.get(&format!("/v1/calibrations/{id}/export?format=c"), ADMIN)
            .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("withdrawn"), "{p}");
}

#[tokio::test]
async fn a_triad_is_stored_once_per_idempotency_key_and_from_csv() {
    let app = TestApp::spawn(Sqlite).await;
    let send = || {
        app.client
            .post(app.url("/v1/calibrations/triad"))
            .bearer_auth(ADMIN)
            .header("Idempotency-Key", "triad-1")
            .json(&known_body())
            .send()
    };
    let first = send().await.unwrap();
    assert_eq!(first.status(), StatusCode::CREATED);
    let first: Value = first.json().await.unwrap();
    let again = send().await.unwrap();
    assert_eq!(again.status(), StatusCode::CREATED);
    assert_eq!(again.headers()["idempotent-replayed"], "true");
    let again: Value = again.json().await.unwrap();
    assert_eq!(again["id"], first["id"]);
    let sensor = app.get_json("/v1/sensors/IMU-7", ADMIN).await;
    assert_eq!(sensor["calibration_count"], 1);

    // CSV: static positions of unknown orientation, the record's fields as
    // `# key: value` lines.
    let res = post_static_csv(
        &app,
        "# sensor_id: IMU-CSV\n# station_id: LAB-5\n# performed_at: 2026-09-01T00:00:00Z\n\
         # unit: g\n",
        [0.01, -0.02, 0.03],
        [1.02, 0.99, 1.01],
    )
    .await;
    let status = res.status();
    let r: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{r}");
    assert_eq!(r["method"], "gravity_magnitude");
    assert_eq!(r["station_id"], "LAB-5");
    let stored = app.get_json("/v1/sensors/IMU-CSV", ADMIN).await;
    assert_eq!(stored["latest"]["triad"]["method"], "gravity_magnitude");
    for (m, want) in [0.01, -0.02, 0.03].iter().enumerate() {
        assert!((f(&r["b"][m]) - want).abs() < 1e-9, "{r}");
    }
    for (m, want) in [1.02, 0.99, 1.01].iter().enumerate() {
        assert!((f(&r["S"][m][m]) - want).abs() < 1e-9, "{r}");
    }
}

/// The guarded rule by hand: pass inside the limits by `u`, fail outside
/// them by `u`, conditional between.
fn guarded(v: f64, u: f64, lo: f64, hi: f64) -> &'static str {
    if lo + u <= v && v <= hi - u {
        "pass"
    } else if v < lo - u || v > hi + u {
        "fail"
    } else {
        "conditional"
    }
}

/// Creates sensor type `id` in `unit` with `limits`, the guarded rule, a
/// year's interval and k = 2.
pub(crate) async fn guarded_type(app: &TestApp, id: &str, unit: &str, limits: &Value) {
    let res = app
        .put(
            &format!("/v1/sensor-types/{id}"),
            ADMIN,
            &json!({"unit": unit, "limits": limits, "decision_rule": "guarded",
                "interval_days": 365, "coverage_factor": 2.0}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
}

/// Each element a type's `k0`, `ki` and `kp` limits judge in triad `r`,
/// judged here by the guarded rule from its stored value and expanded
/// uncertainty: `(element, verdict, value, U)`. Without known orientations
/// the frame convention's zeros (`S` above the diagonal) are not judged.
fn judged_by_hand(r: &Value, limits: &Value) -> Vec<(String, &'static str, f64, f64)> {
    let axes = ["x", "y", "z"];
    let known = r["method"] == "known_orientations";
    let mut want = Vec::new();
    for m in 0..3 {
        for (term, column) in [("k0", None), ("ki", Some(m)), ("kp", Some((m + 1) % 3))] {
            if limits.get(term).is_none() {
                continue;
            }
            let (name, v, u) = match column {
                None => (
                    format!("b_{}", axes[m]),
                    f(&r["b"][m]),
                    f(&r["b_expanded"][m]),
                ),
                Some(k) if !known && k > m => continue,
                Some(k) => (
                    format!("S_{}{}", axes[m], axes[k]),
                    f(&r["S"][m][k]),
                    f(&r["S_expanded"][m][k]),
                ),
            };
            let (lo, hi) = (f(&limits[term]["min"]), f(&limits[term]["max"]));
            want.push((name, guarded(v, u, lo, hi), v, u));
        }
    }
    want
}

/// The decision's elements are exactly `want`, each with its verdict,
/// value and U; answers the worst verdict.
fn assert_judged(decision: &Value, want: &[(String, &'static str, f64, f64)]) -> &'static str {
    let elements = decision["elements"].as_object().unwrap();
    assert_eq!(elements.len(), want.len(), "{decision}");
    let mut worst = "pass";
    for (name, verdict, v, u) in want {
        let e = &elements[name];
        assert_eq!(e["verdict"], *verdict, "{name}: {e}");
        assert_eq!((f(&e["value"]), f(&e["expanded"])), (*v, *u), "{name}");
        if *verdict == "fail" || (*verdict == "conditional" && worst == "pass") {
            worst = verdict;
        }
    }
    assert_eq!(decision["verdict"], worst);
    worst
}

/// The printed certificate's row `name` states `v` and `U` rounded to U's
/// second significant digit (computed here); its columns: value, standard
/// error, u_c, ν_eff, k, p, U.
fn assert_rounded_row(html: &str, name: &str, v: f64, u: f64) {
    let decimals = (1 - u.log10().floor() as i32).max(0) as usize;
    let cells = certificate_row(html, name);
    assert_eq!(cells[0], format!("{v:.decimals$}"), "{name}");
    assert_eq!(cells[6], format!("{u:.decimals$}"), "{name}");
}

/// The printed certificate's row `name` states the element's ν_eff, k (to
/// two decimals) and p (in per cent) as the stored result does.
fn assert_coverage_row(html: &str, name: &str, stored: &Value) {
    let c = &stored["coverage"][name];
    let cells = certificate_row(html, name);
    let k = format!("{:.2}", f(&c["coverage_factor"]));
    let k = k.trim_end_matches('0').trim_end_matches('.');
    assert_eq!(
        (cells[3].as_str(), cells[4].as_str(), cells[5].as_str()),
        (
            c["effective_dof"].to_string().as_str(),
            k,
            format!("{:.2} %", 100.0 * f(&c["coverage_probability"])).as_str()
        ),
        "{name}"
    );
}

#[rstest]
#[tokio::test]
async fn a_typed_triad_is_judged_element_by_element(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let limits = json!({
        "k0": {"min": -0.15, "max": 0.15},
        "ki": {"min": 9.7, "max": 9.9},
        "kp": {"min": -0.0305, "max": 0.0305},
    });
    guarded_type(&app, "IMU-NAV", "m/s2", &limits).await;
    let mut body = known_body();
    body["sensor_type"] = json!("IMU-NAV");
    body["performed_at"] = json!("2026-10-01T00:00:00Z");
    body["stand"] = json!({"angle_std_arcsec": 20.0, "gravity_rel_std": 1e-5});
    let r = store(&app, ADMIN, &body).await;
    let d = &r["decision"];
    assert_eq!(d["rule"], "guarded");
    // Every limited term of every axis, named by its element, judged by hand
    // with the stored value and expanded uncertainty.
    let worst = assert_judged(d, &judged_by_hand(&r, &limits));
    assert_eq!(d["elements"].as_object().unwrap().len(), 9);
    assert!(d["elements"].get("S_xz").is_none(), "ko is not limited");
    assert_eq!(worst, "fail", "b_y = −0.21 lies outside ±0.15");
    // The verdict and due date are the sensor's, as for a single axis.
    let sensor = app.get_json("/v1/sensors/IMU-7", ADMIN).await;
    assert_eq!(sensor["sensor_type"], "IMU-NAV");
    assert_eq!(sensor["latest_verdict"], "fail");
    assert_eq!(sensor["due_at"], "2027-10-01T00:00:00.000000Z");
    assert_eq!(sensor["status"], "failed");
    let res = app
        .post(
            "/v1/sensors/IMU-7/compensate?require=usable",
            ADMIN,
            &json!({"outputs": [[0.1, 0.2, 9.8]]}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CONFLICT);

    // From the gravity magnitude: judged on the elements the fit measures
    // (kp's S_xy and S_yz are zero by the frame convention; S_zx is
    // measured), and the note says which are not.
    let res = post_static_csv(
        &app,
        "# sensor_id: IMU-7\n# unit: m/s2\n",
        [0.1, -0.1, 0.05],
        [9.8, 9.8, 9.8],
    )
    .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let g: Value = res.json().await.unwrap();
    let judged: Vec<&String> = g["decision"]["elements"]
        .as_object()
        .unwrap()
        .keys()
        .collect();
    assert_eq!(
        judged,
        ["S_xx", "S_yy", "S_zx", "S_zz", "b_x", "b_y", "b_z"],
        "{g}"
    );
    assert_eq!(g["decision"]["verdict"], "pass");
    let note = g["decision_note"].as_str().unwrap();
    assert!(
        note.contains("S_xy, S_xz and S_yz") && note.contains("IMU-NAV"),
        "{note}"
    );
    let sensor = app.get_json("/v1/sensors/IMU-7", ADMIN).await;
    assert_eq!(sensor["latest_verdict"], "pass");

    // A type limiting a term a triad does not identify is refused.
    let res = app
        .put(
            "/v1/sensor-types/SECOND-ORDER",
            ADMIN,
            &json!({"unit": "m/s2", "limits": {"kii": {"max": 0.01}}, "decision_rule": "simple"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let mut body = known_body();
    body["sensor_id"] = json!("IMU-8");
    body["sensor_type"] = json!("SECOND-ORDER");
    let p = problem(
        app.post("/v1/calibrations/triad", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/sensor_type"], "{p}");
    assert!(p["detail"].as_str().unwrap().contains("kii"), "{p}");
    assert!(app.get("/v1/sensors/IMU-8", ADMIN).await.status() == StatusCode::NOT_FOUND);
}

/// The numbers of a certificate's results row for `element`.
fn certificate_row(html: &str, element: &str) -> Vec<String> {
    let start = html
        .find(&format!("data-element=\"{element}\""))
        .unwrap_or_else(|| panic!("no row {element}"));
    let row = &html[start..start + html[start..].find("</tr>").unwrap()];
    row.split("<td class=\"num\">")
        .skip(1)
        .map(|cell| cell[..cell.find("</td>").unwrap()].to_owned())
        .collect()
}

#[tokio::test]
async fn a_triads_certificate_states_every_element_rounded_to_its_uncertainty() {
    use sha2::{Digest, Sha256};
    let app = TestApp::spawn(Sqlite).await;
    let mut body = known_body();
    body["stand"] = json!({"angle_std_arcsec": 20.0, "gravity_rel_std": 1e-5});
    let stored = store(&app, ADMIN, &body).await;
    let id = stored["id"].as_str().unwrap();
    let res = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.headers()[CONTENT_TYPE], "text/html; charset=utf-8");
    let html = res.text().await.unwrap();
    assert!(html.contains("(accelerometer triad)"));
    // The stored submission's digest: the bytes sent.
    let sent = serde_json::to_vec(&body).unwrap();
    assert!(html.contains(&hex::encode(Sha256::digest(&sent))));
    // Every element of b and S: value and U to U's second significant
    // digit (computed here), and the standard error.
    let axes = ["x", "y", "z"];
    for m in 0..3 {
        let mut elements = vec![(
            format!("b_{}", axes[m]),
            stored["b"][m].clone(),
            stored["b_expanded"][m].clone(),
        )];
        for k in 0..3 {
            elements.push((
                format!("S_{}{}", axes[m], axes[k]),
                stored["S"][m][k].clone(),
                stored["S_expanded"][m][k].clone(),
            ));
        }
        for (name, v, u) in elements {
            assert_rounded_row(&html, &name, f(&v), f(&u));
            assert_coverage_row(&html, &name, &stored);
        }
    }
    assert!(
        html.contains("for a coverage probability of 95.45 %"),
        "the coverage stated"
    );
    assert!(html.contains("The results relate only to the item calibrated"));
    assert!(html.contains(&format!("End of certificate No. {id}")));
}

/// Known orientations with each axis's second-order term: the faces and
/// four tilts, six runs scattered by 1e-4 m/s².
fn curved_body() -> (Value, [f64; 3]) {
    let (b, s) = super::triad::truth();
    let s2 = [0.012, -0.009, 0.015];
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let mut positions = faces();
    positions.extend([[h, h, 0.0], [0.0, h, -h], [-h, 0.0, h], [0.6, 0.0, 0.8]]);
    let runs: Vec<Value> = (0..6)
        .map(|j| {
            let samples: Vec<Value> = positions
                .iter()
                .enumerate()
                .map(|(p, g)| {
                    let u = [0, 1, 2].map(|m| {
                        b[m] + (0..3).map(|k| s[m][k] * g[k]).sum::<f64>()
                            + s2[m] * g[m] * g[m]
                            + 1e-4 * (((j * 7 + p * 3 + m * 5) % 11) as f64 - 5.0) / 5.0
                    });
                    json!([u])
                })
                .collect();
            json!({ "samples": samples })
        })
        .collect();
    (
        json!({"sensor_id": "IMU-9", "unit": "m/s2", "orientations": positions, "runs": runs,
            "batches": 2, "second_order": true}),
        s2,
    )
}

#[tokio::test]
async fn second_order_terms_are_identified_per_axis_and_compensated_by_newton() {
    let app = TestApp::spawn(Sqlite).await;
    let (body, s2) = curved_body();
    let r = store(&app, ADMIN, &body).await;
    assert_eq!(r["model"], "u = b + S g + S2 * g^2 (S2_m g_m^2 on axis m)");
    let id = r["id"].as_str().unwrap().to_owned();
    // Each axis is the single-axis method with `kii`, bit for bit.
    let positions = body["orientations"].as_array().unwrap();
    for m in 0..3 {
        let single = json!({
            "sensor_id": format!("IMU-9-{m}"), "unit": "m/s2",
            "model": ["k0", "ki", "kp", "ko", "kii"],
            "positions": positions.iter().map(|g| json!({"a": [g[m].clone(), g[(m + 1) % 3].clone(), g[(m + 2) % 3].clone()]})).collect::<Vec<_>>(),
            "runs": body["runs"].as_array().unwrap().iter().map(|run| json!({"readings":
                run["samples"].as_array().unwrap().iter().map(|at| json!([at[0][m].clone()])).collect::<Vec<_>>()})).collect::<Vec<_>>(),
            "batches": 2,
        });
        let one: Value = app
            .post("/v1/identify", ADMIN, &single)
            .await
            .json()
            .await
            .unwrap();
        let c = &one["fused"]["coefficients"];
        assert_eq!(r["S2"][m], c["kii"], "axis {m}: {one}");
        assert_eq!(r["b"][m], c["k0"]);
        assert_eq!(r["S"][m][m], c["ki"]);
        assert_eq!(r["S2_std_errors"][m], one["fused"]["std_errors"]["kii"]);
        assert_eq!(
            r["S2_expanded"][m],
            one["uncertainty"]["terms"]["kii"]["expanded"]
        );
        assert!(
            (f(&r["S2"][m]) - s2[m]).abs() < 1e-3,
            "S2[{m}] = {}",
            r["S2"][m]
        );
    }
    let stored = app.get_json("/v1/sensors/IMU-9", ADMIN).await;
    assert_eq!(
        stored["latest"]["model"],
        json!(["k0", "ki", "kp", "ko", "kii"])
    );
    assert_eq!(stored["latest"]["triad"]["S2"], r["S2"]);

    // Compensation solves u = b + S g + S2 ⊙ g² (built here from the
    // stored elements) for g; the linear inverse would be off by ~S2/S.
    let (b, s, q) = (vector(&r["b"]), matrix(&r["S"]), vector(&r["S2"]));
    let gs = [[0.0, 0.0, 1.0], [0.6, -0.8, 0.0], [0.3, 0.4, -0.2]];
    let outputs: Vec<[f64; 3]> = gs
        .iter()
        .map(|g| {
            [0, 1, 2]
                .map(|m| b[m] + (0..3).map(|k| s[m][k] * g[k]).sum::<f64>() + q[m] * g[m] * g[m])
        })
        .collect();
    let c: Value = app
        .post(
            "/v1/sensors/IMU-9/compensate",
            ADMIN,
            &json!({ "outputs": outputs }),
        )
        .await
        .json()
        .await
        .unwrap();
    for (k, g) in gs.iter().enumerate() {
        for m in 0..3 {
            assert!((f(&c["g"][k][m]) - g[m]).abs() < 1e-12, "g{k}{m}: {c}");
        }
    }
    // Below what the curved x axis can output (its minimum is about
    // b − S_xx²/(4 S2_x) ≈ −2005 m/s²): refused at the triple.
    let p = problem(
        app.post(
            "/v1/sensors/IMU-9/compensate",
            ADMIN,
            &json!({"outputs": [[0.1, 0.1, 0.1], [-1.0e4, 0.0, 0.0]]}),
        )
        .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/outputs/1"], "{p}");

    // The diagonal formats cannot carry S2; json and c do.
    let p = problem(
        app.get(&format!("/v1/calibrations/{id}/export?format=px4"), ADMIN)
            .await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(
        p["detail"].as_str().unwrap().contains("second-order"),
        "{p}"
    );
    let j: Value = app
        .get(&format!("/v1/calibrations/{id}/export?format=json"), ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(j["S2"], r["S2"]);
    let html = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await
        .text()
        .await
        .unwrap();
    assert_rounded_row(&html, "S2_y", f(&r["S2"][1]), f(&r["S2_expanded"][1]));

    // Without known orientations there is no second-order fit.
    let unknown = json!({"sensor_id": "IMU-10", "second_order": true,
        "static_positions": vec![vec![[1.0, 0.0, 0.0]]; 9]});
    let p = problem(
        app.post("/v1/calibrations/triad", ADMIN, &unknown).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert!(pointers(&p).contains(&"/second_order".to_owned()), "{p}");
}

#[rstest]
#[tokio::test]
async fn a_triads_standards_enter_its_budget_its_certificate_and_the_reverse_trace(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let stand: Value =
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap();
    let res = app.put("/v1/standards/STAND-1", ADMIN, &stand).await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let mut body = known_body();
    body["performed_at"] = json!("2026-03-01T00:00:00Z");
    body["standards"] = json!({"stand": "STAND-1"});
    let r = store(&app, ADMIN, &body).await;
    assert_eq!(r["standards"][0]["standard_id"], "STAND-1");
    assert_eq!(r["standards"][0]["role"], "stand");
    // The registered stand's indexing error is the budget's: the same as
    // naming it by value.
    let mut by_value = known_body();
    by_value["stand"] =
        json!({"angle_std_arcsec": stand["angle_std_arcsec"], "gravity_rel_std": 0.0});
    let v: Value = app
        .post("/v1/identify/triad", ADMIN, &by_value)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(r["S_expanded"], v["S_expanded"]);
    assert_eq!(r["axes"][1]["uncertainty"], v["axes"][1]["uncertainty"]);
    // The certificate states the standard and its traceability.
    let id = r["id"].as_str().unwrap().to_owned();
    let html = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await
        .text()
        .await
        .unwrap();
    assert!(html.contains("CAL-2026-0117"));
    assert!(html.contains("traceable to the SI through the reference standards"));

    // Refusals: an unknown standard, `stand` beside `standards`, and the
    // computation that stores nothing.
    let mut unknown = known_body();
    unknown["standards"] = json!({"stand": "NOPE"});
    let p = problem(
        app.post("/v1/calibrations/triad", ADMIN, &unknown).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/standards/stand"]);
    let mut both = body.clone();
    both["stand"] = json!({"angle_std_arcsec": 1.0, "gravity_rel_std": 0.0});
    let p = problem(
        app.post("/v1/calibrations/triad", ADMIN, &both).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/stand"]);
    let p = problem(
        app.post("/v1/identify/triad", ADMIN, &body).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/standards"]);

    // The stand found nonconforming: the triad made with it is held.
    let nc = json!({"found_at": "2026-04-15T00:00:00Z",
        "last_known_good_at": "2026-02-15T00:00:00Z", "reason": "Indexing error at the 90° stop."});
    let res = app
        .post("/v1/standards/STAND-1/nonconformity", ADMIN, &nc)
        .await;
    assert_eq!(res.status(), StatusCode::CREATED);
    let traced: Value = res.json().await.unwrap();
    assert_eq!(traced["calibrations"][0]["calibration_id"], id.as_str());
    assert_eq!(traced["calibrations"][0]["state"], "under_review");
    let c = app.get_json("/v1/sensors/IMU-7/coefficients", ADMIN).await;
    assert_eq!(c["usable"], false, "{c}");
}

/// A triad from the gravity magnitude with a noisy twenty-position set,
/// stored under a typed sensor: its budget makes expanded uncertainties for
/// b and S, which the decision judges (by hand here, with the guarded rule)
/// and the certificate states rounded to them; the planted S lies within
/// them. With exactly nine positions there is no uncertainty: not judged,
/// and the note says why.
#[rstest]
#[tokio::test]
async fn a_triad_from_the_gravity_magnitude_is_judged_and_certified_with_its_budget(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let limits = json!({
        "k0": {"min": -0.05, "max": 0.05},
        "ki": {"min": 0.97, "max": 1.03},
        "kp": {"min": -0.02, "max": 0.02},
    });
    guarded_type(&app, "IMU-G", "g", &limits).await;
    let body = json!({"sensor_id": "IMU-G", "unit": "g", "sensor_type": "IMU-G",
        "stand": {"gravity_rel_std": 2e-5},
        "static_positions": gravity_positions(20, 0x5eed_1234_abcd_0001)});
    let r = store(&app, ADMIN, &body).await;
    assert_eq!(r["method"], "gravity_magnitude");
    let (s_true, axes) = (lower_s(), ["x", "y", "z"]);
    // The planted S within the expanded uncertainty, element by element.
    for m in 0..3 {
        for k in 0..=m {
            let (v, u) = (f(&r["S"][m][k]), f(&r["S_expanded"][m][k]));
            assert!(
                u > 0.0 && (v - s_true[m][k]).abs() < u,
                "S{m}{k}: {v} vs {} ± {u}",
                s_true[m][k]
            );
        }
    }
    // Every measured element judged by hand from the stored value and U.
    let want = judged_by_hand(&r, &limits);
    assert_eq!(
        want.len(),
        7,
        "b, S's diagonal and S_zx: S_xy and S_yz are the convention's"
    );
    assert_judged(&r["decision"], &want);
    let sensor = app.get_json("/v1/sensors/IMU-G", ADMIN).await;
    assert_eq!(sensor["latest_verdict"], r["decision"]["verdict"]);
    assert_eq!(sensor["latest"]["triad"]["S_std_errors"], r["S_std_errors"]);
    assert_eq!(sensor["latest"]["triad"]["S_expanded"], r["S_expanded"]);

    // The certificate: b and S's measured elements rounded to U (computed
    // here), the convention's zeros said as such.
    let id = r["id"].as_str().unwrap();
    let html = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await
        .text()
        .await
        .unwrap();
    for m in 0..3 {
        let mut elements = vec![(format!("b_{}", axes[m]), &r["b"][m], &r["b_expanded"][m])];
        for k in 0..=m {
            elements.push((
                format!("S_{}{}", axes[m], axes[k]),
                &r["S"][m][k],
                &r["S_expanded"][m][k],
            ));
        }
        for (name, v, u) in elements {
            assert_rounded_row(&html, &name, f(v), f(u));
        }
    }
    for fixed in ["S_xy", "S_xz", "S_yz"] {
        let start = html.find(&format!("data-element=\"{fixed}\"")).unwrap();
        let row = &html[start..start + html[start..].find("</tr>").unwrap()];
        assert!(row.contains("by the frame convention"), "{row}");
    }
    assert!(html.contains("degrees of freedom"));

    // Nine positions (the six faces and three corners): no degree of
    // freedom, no uncertainty, not judged.
    let c = 1.0 / 3f64.sqrt();
    let mut dirs = faces();
    dirs.extend([[c, c, c], [-c, c, c], [c, -c, c]]);
    let nine = json!({"sensor_id": "IMU-G", "unit": "g",
        "static_positions": positions_at(&dirs, 0x5eed_1234_abcd_0002)});
    let g = store(&app, ADMIN, &nine).await;
    assert_eq!(g["fit"]["degrees_of_freedom"], 0);
    assert!(
        g.get("decision").is_none() && g.get("uncertainty").is_none(),
        "{g}"
    );
    assert!(
        g.get("S_expanded").is_none() && g["S_std_errors"].is_null(),
        "{g}"
    );
    assert!(
        g["decision_note"]
            .as_str()
            .unwrap()
            .contains("no degree of freedom"),
        "{g}"
    );

    // A stand cannot be named for a fit that uses no orientation.
    let stand: Value =
        serde_json::from_str(include_str!("../../examples/standard-stand.json")).unwrap();
    assert_eq!(
        app.put("/v1/standards/STAND-1", ADMIN, &stand)
            .await
            .status(),
        StatusCode::CREATED
    );
    let mut named = body.clone();
    named["stand"] = Value::Null;
    named["standards"] = json!({"stand": "STAND-1"});
    let p = problem(
        app.post("/v1/calibrations/triad", ADMIN, &named).await,
        StatusCode::UNPROCESSABLE_ENTITY,
    )
    .await;
    assert_eq!(pointers(&p), ["/standards/stand"], "{p}");
}

/// Superseding and reprocessing a triad: a corrected triad replaces it in
/// one act (the new one computed as `POST /v1/identify/triad` computes the
/// corrected body, recording what it supersedes; the old one superseded,
/// its signature naming the new); reprocessing confirms a triad whose
/// numbers are today's, and supersedes one stored by an older method — a
/// triad from the gravity magnitude stored without `S`'s standard errors,
/// inserted here as such — naming every element that changed.
#[rstest]
#[tokio::test]
async fn a_triad_is_superseded_by_a_corrected_triad_and_reprocessed(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    let mut wrong = known_body();
    wrong["performed_at"] = json!("2026-10-01T08:00:00Z");
    let a = store(&app, ADMIN, &wrong).await["id"].clone();
    let a_id = a.as_str().unwrap().to_owned();
    let mut right = wrong.clone();
    right["performed_at"] = json!("2026-10-02T08:00:00Z");
    right["batches"] = json!(3);
    let res = app
        .post(
            &format!("/v1/calibrations/{a_id}/supersede?reason=wrong%20batches"),
            &rita,
            &right,
        )
        .await;
    let location = res.headers().get(LOCATION).cloned();
    let text = res.text().await.unwrap();
    let b: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(b["kind"], "triad", "{text}");
    let b_id = b["id"].as_str().unwrap().to_owned();
    assert_eq!(
        location.unwrap().to_str().unwrap(),
        format!("/v1/calibrations/{b_id}")
    );
    assert_eq!(
        b["supersedes"],
        json!({"calibration_id": a, "reason": "wrong batches"})
    );
    // The corrected body's numbers, as computed without storing.
    let mut plain = right.clone();
    plain.as_object_mut().unwrap().remove("performed_at");
    let computed: Value = app
        .post("/v1/identify/triad", ADMIN, &plain)
        .await
        .json()
        .await
        .unwrap();
    for key in [
        "b",
        "S",
        "T",
        "b_std_errors",
        "S_std_errors",
        "S_expanded",
        "residuals",
    ] {
        assert_eq!(b[key], computed[key], "{key}");
    }
    let record = app
        .get_json(&format!("/v1/calibrations/{a_id}/signatures"), ADMIN)
        .await;
    assert_eq!(record["state"], "superseded");
    assert_eq!(record["signatures"][0]["superseded_by"], b_id.as_str());
    assert_eq!(
        app.get_json("/v1/sensors/IMU-7", ADMIN).await["latest"]["id"],
        b_id.as_str()
    );
    assert_eq!(
        app.get_json(&format!("/v1/calibrations/{b_id}"), ADMIN)
            .await,
        b
    );
    // The page and the certificate say what it replaces.
    let (session, _) = super::ui::sign_in(&app, ADMIN).await;
    let page = super::ui::page(&app, &format!("/ui/calibrations/{b_id}"), &session)
        .await
        .text()
        .await
        .unwrap();
    assert!(
        page.contains("This calibration supersedes") && page.contains(&a_id),
        "{page}"
    );
    // A triad's page is the one calibration page: a reviewer sees its
    // audit trail too, as for a single axis.
    let trail = &page[page.find(r#"<table id="audit">"#).expect("a trail")..];
    let rows: Vec<&str> = trail
        .match_indices(r#"<tr data-action=""#)
        .map(|(i, m)| trail[i + m.len()..].split('"').next().unwrap())
        .collect();
    assert_eq!(rows, ["calibration.submitted"], "{trail}");
    let certificate = app
        .get(&format!("/v1/calibrations/{b_id}/certificate"), ADMIN)
        .await
        .text()
        .await
        .unwrap();
    assert!(certificate.contains(&format!("replaces certificate No. <code>{a_id}</code>")));
    // Superseded once.
    let p = problem(
        app.post(
            &format!("/v1/calibrations/{a_id}/supersede?reason=again"),
            &rita,
            &right,
        )
        .await,
        StatusCode::CONFLICT,
    )
    .await;
    assert!(p["detail"].as_str().unwrap().contains("superseded"), "{p}");

    // Reprocessing the corrected triad: today's numbers, confirmed.
    let reprocess = |id: String| {
        let (app, rita) = (&app, &rita);
        async move {
            let res = app
                .post(
                    &format!("/v1/calibrations/{id}/reprocess"),
                    rita,
                    &json!({}),
                )
                .await;
            assert_eq!(res.status(), StatusCode::OK);
            res.json::<Value>().await.unwrap()
        }
    };
    let r = reprocess(b_id.clone()).await;
    assert_eq!(r["outcome"], "confirmed", "{r}");
    assert_eq!(r["changed"], json!([]));
    assert_eq!(r["signature"]["action"], "confirm");

    // A triad from the gravity magnitude stored by an older method, without
    // S's standard errors and expanded uncertainties.
    let body = json!({"sensor_id": "IMU-OLD", "unit": "g",
        "static_positions": gravity_positions(16, 0x0bad_cafe_0000_0001)});
    let truth: Value = app
        .post("/v1/identify/triad", ADMIN, &body)
        .await
        .json()
        .await
        .unwrap();
    let store = accelcal::store::open(&app.db().url).await.unwrap();
    let old_id = uuid::Uuid::now_v7();
    let at = accelcal::domain::timestamp::Timestamp::parse("2026-11-01T00:00:00Z").unwrap();
    let elements = accelcal::store::TriadElements {
        method: "gravity_magnitude".into(),
        b: vector(&truth["b"]),
        b_std_errors: Some(vector(&truth["b_std_errors"])),
        s: matrix(&truth["S"]),
        s_std_errors: None,
        t: matrix(&truth["T"]),
        t_std_errors: Some(matrix(&truth["T_std_errors"])),
        b_expanded: None,
        s_expanded: None,
        s2: None,
        s2_std_errors: None,
        s2_expanded: None,
    };
    store
        .insert_calibration(
            accelcal::store::NewCalibration {
                id: old_id,
                sensor_id: "IMU-OLD".into(),
                station_id: None,
                performed_at: at,
                received_at: at,
                unit: "g".into(),
                model: accelcal_core::Model::new(vec![
                    accelcal_core::Term::K0,
                    accelcal_core::Term::Ki,
                    accelcal_core::Term::Kp,
                    accelcal_core::Term::Ko,
                ])
                .unwrap(),
                runs: 1,
                coefficients: accelcal_core::TermMap(Vec::new()),
                std_errors: accelcal_core::TermMap(Vec::new()),
                result: bytes::Bytes::from(truth.to_string()),
                submission: bytes::Bytes::from(body.to_string()),
                content_type: "application/json".into(),
                submitted_by: "env-admin".into(),
                sensor_type: None,
                assigns_type: false,
                verdict: None,
                due_at: None,
                expanded: None,
                triad: Some(Box::new(elements)),
                thermal: None,
                thermal_triad: None,
                standards: Vec::new(),
                fitted_from: Vec::new(),
            },
            None,
        )
        .await
        .unwrap();
    store.close().await;
    let r = reprocess(old_id.to_string()).await;
    assert_eq!(r["outcome"], "superseded", "{r}");
    // What changed: S's standard errors (six below the diagonal and the
    // convention's three zeros) and the expanded uncertainties of b and S.
    let mut want = Vec::new();
    for (name, suffix) in [("S", "_std_error"), ("b", "_expanded"), ("S", "_expanded")] {
        for row in ["x", "y", "z"] {
            if name == "b" {
                want.push(format!("b_{row}{suffix}"));
                continue;
            }
            for column in ["x", "y", "z"] {
                want.push(format!("S_{row}{column}{suffix}"));
            }
        }
    }
    let mut changed: Vec<String> = r["changed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap().to_owned())
        .collect();
    changed.sort();
    want.sort();
    assert_eq!(changed, want);
    let new = r["replacement_id"].as_str().unwrap();
    let result = app
        .get_json(&format!("/v1/calibrations/{new}"), ADMIN)
        .await;
    for key in ["b", "S", "T", "S_std_errors", "S_expanded", "uncertainty"] {
        assert_eq!(result[key], truth[key], "today's {key}, bit for bit");
    }
    assert_eq!(result["received_at"], "2026-11-01T00:00:00.000000Z");
    assert_eq!(result["supersedes"]["calibration_id"], old_id.to_string());
    assert!(
        r["signature"]["comment"]
            .as_str()
            .unwrap()
            .contains("S_yx_std_error"),
        "{r}"
    );
}

/// A triad calibrated once with second-order terms and once without:
/// its stability covers the elements both calibrations have (b, S, T), not
/// S2 — written once over named quantities, as a single axis's terms are.
#[tokio::test]
async fn stability_covers_the_elements_every_calibration_has() {
    let app = TestApp::spawn(Sqlite).await;
    let (mut curved, _) = curved_body();
    curved["performed_at"] = json!("2026-01-01T00:00:00Z");
    let first = store(&app, ADMIN, &curved).await;
    let mut plain = curved.clone();
    plain["second_order"] = json!(false);
    plain["performed_at"] = json!("2026-06-01T00:00:00Z");
    let second = store(&app, ADMIN, &plain).await;
    assert!(second.get("S2").is_none_or(Value::is_null), "{second}");
    let res = app.get("/v1/sensors/IMU-9/stability", ADMIN).await;
    assert_eq!(res.status(), StatusCode::OK);
    let s: Value = res.json().await.unwrap();
    let elements = s["elements"].as_object().unwrap();
    assert_eq!(s["calibrations"], 2);
    assert!(
        !elements.keys().any(|k| k.starts_with("S2")),
        "{elements:?}"
    );
    assert_eq!(elements.len(), 3 + 9 + 9, "b, S and T");
    // The figures are the stored values': b_x's mean and latest change.
    let (x0, x1) = (f(&first["b"][0]), f(&second["b"][0]));
    assert!((f(&elements["b_x"]["mean"]) - (x0 + x1) / 2.0).abs() < 1e-12);
    assert!((f(&elements["b_x"]["latest_change"]) - (x1 - x0)).abs() < 1e-12);
    // The sensor's page, which charts them, is drawn too.
    let (session, _) = super::ui::sign_in(&app, ADMIN).await;
    let page = super::ui::page(&app, "/ui/sensors/IMU-9", &session).await;
    assert_eq!(page.status(), StatusCode::OK);
    let page = page.text().await.unwrap();
    assert!(page.contains("id=\"chart-b_x\"") && page.contains("id=\"chart-S2_x\""));
}
