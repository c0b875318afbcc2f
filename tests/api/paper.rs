//! The paper's submission end to end (NOTES §5 through the service).

use reqwest::StatusCode;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{self, Postgres, Sqlite};
use accelcal_testkit::*;
use rstest::rstest;

const TABLE2_ALPHA: [f64; 6] = [
    0.006091826,
    0.006149912,
    0.006163094,
    0.006287309,
    0.006297850,
    0.006274837,
];

/// The independent reference figures (`core/tests/data/reference.py`:
/// closed forms in 50-digit decimals).
fn reference() -> Value {
    serde_json::from_str(include_str!("../../core/tests/data/reference.json")).unwrap()
}

/// `got` within `relative` of `want`.
#[track_caller]
fn near(got: &Value, want: &Value, relative: f64) {
    let (g, w) = (got.as_f64().unwrap(), want.as_f64().unwrap());
    assert!(
        (g - w).abs() <= relative * w.abs(),
        "{g:e} vs reference {w:e}"
    );
}

/// Every figure of a Table 1 result against the reference: per-run
/// coefficients and standard errors, mean, fused, standard errors, eq. 8
/// about both (absolute and relative), batches and normalised values.
fn check_paper_result(r: &Value) {
    let reference = reference();
    let t1 = &reference["table1"];
    let runs = r["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 6);
    for (j, (run, alpha)) in runs.iter().zip(TABLE2_ALPHA).enumerate() {
        for t in ["k0", "ki", "kp"] {
            near(
                &run["coefficients"][t],
                &t1["runs"][j]["coefficients"][t],
                1e-12,
            );
            near(&run["std_errors"][t], &t1["runs"][j]["std_errors"][t], 1e-9);
        }
        near(&run["residual_rms"], &t1["runs"][j]["residual_rms"], 1e-9);
        // α per run agrees with Table 2's printed α (NOTES §5).
        close(&run["coefficients"]["kp"], alpha, 1e-9);
        assert_eq!(run["dof"], 1);
    }
    for t in ["k0", "ki", "kp"] {
        near(&r["mean"]["coefficients"][t], &t1["mean"][t], 1e-12);
        near(&r["mean"]["dispersion"][t], &t1["mean_dispersion"][t], 1e-9);
        near(
            &r["mean"]["relative_dispersion"][t],
            &t1["mean_relative_dispersion"][t],
            1e-9,
        );
        near(&r["fused"]["coefficients"][t], &t1["fused"][t], 1e-12);
        near(
            &r["fused"]["std_errors"][t],
            &t1["fused_std_error"][t],
            1e-9,
        );
        near(
            &r["fused"]["dispersion"][t],
            &t1["fused_dispersion"][t],
            1e-9,
        );
        near(
            &r["fused"]["relative_dispersion"][t],
            &t1["fused_relative_dispersion"][t],
            1e-9,
        );
        for p in 0..2 {
            near(
                &r["fused"]["batches"][p]["mean"][t],
                &t1["batch_mean"][t][p],
                1e-12,
            );
            near(
                &r["fused"]["batches"][p]["std"][t],
                &t1["batch_std"][t][p],
                1e-9,
            );
        }
    }
    // Table 1's own fused SE of α, 6.3637e-6 — not Table 2's 6.3639e-6.
    close(&r["fused"]["std_errors"]["kp"], 6.3637e-6, 0.5e-10);
    assert_eq!(r["fused"]["batches"][0]["runs"], json!([0, 1, 2]));
    assert_eq!(r["fused"]["batches"][1]["runs"], json!([3, 4, 5]));
    assert_eq!(r["positions"][1]["a"], json!([-1.0, 0.0, 0.0]));
    close(&r["condition_number"], std::f64::consts::SQRT_2, 1e-12);
    near(
        &r["normalized"]["bias_g"],
        &t1["normalized"]["bias_g"],
        1e-12,
    );
    near(
        &r["normalized"]["misalignment_p_rad"],
        &t1["normalized"]["misalignment_p_rad"],
        1e-12,
    );
}

#[rstest]
#[tokio::test]
async fn paper_submission_end_to_end(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let body = include_str!("../../examples/paper-table1.json");
    let res = app
        .client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(ADMIN)
        .header("content-type", "application/json")
        .body(body)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::CREATED);
    let location = res.headers()["location"].to_str().unwrap().to_owned();
    let created: Value = res.json().await.unwrap();
    let id = created["id"].as_str().unwrap();
    assert_eq!(location, format!("/v1/calibrations/{id}"));
    assert_eq!(uuid::Uuid::parse_str(id).unwrap().get_version_num(), 7);
    check_paper_result(&created);
    assert_eq!(created["sensor_id"], "PAPER-2005");
    assert_eq!(created["performed_at"], "2005-08-01T00:00:00.000000Z");
    assert_eq!(created["station_id"], Value::Null);

    // GET returns the same document.
    let got: Value = app.get(&location, ADMIN).await.json().await.unwrap();
    assert_eq!(got, created);

    // The submission comes back byte for byte, with its media type.
    let res = app.get(&format!("{location}/submission"), ADMIN).await;
    assert_eq!(res.status(), StatusCode::OK);
    assert_eq!(res.headers()["content-type"], "application/json");
    assert_eq!(res.bytes().await.unwrap(), body.as_bytes());

    // The fused coefficients are what a control system loads.
    let c: Value = app
        .get("/v1/sensors/PAPER-2005/coefficients", ADMIN)
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(c["calibration_id"], created["id"]);
    assert_eq!(c["coefficients"], created["fused"]["coefficients"]);
    assert_eq!(c["std_errors"], created["fused"]["std_errors"]);
    assert_eq!(c["model"], json!(["k0", "ki", "kp"]));
}

#[rstest]
#[tokio::test]
async fn paper_table_as_csv_gives_the_same_numbers(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let csv = paper_csv();
    let res = app
        .client
        .post(app.url("/v1/calibrations"))
        .bearer_auth(ADMIN)
        .header("content-type", "text/csv")
        .body(csv.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), StatusCode::CREATED);
    let r: Value = res.json().await.unwrap();
    check_paper_result(&r);
    assert_eq!(r["sensor_id"], "PAPER-CSV");
    let res = app
        .get(
            &format!("/v1/calibrations/{}/submission", r["id"].as_str().unwrap()),
            ADMIN,
        )
        .await;
    assert_eq!(res.headers()["content-type"], "text/csv");
    assert_eq!(res.text().await.unwrap(), csv);
}

#[rstest]
#[tokio::test]
async fn table_2_fusion_over_http(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let body = json!({
        "values": {
            "ki": [-1.216171962, -1.216049106, -1.216196948, -1.216195816, -1.216184389, -1.216080200],
            "k0": [-0.0008222, -0.0008709, -0.0008703, -0.0008426, -0.0008339, -0.0008544],
            "kp": TABLE2_ALPHA
        },
        "batches": 2
    });
    let res = app.post("/v1/fuse", ADMIN, &body).await;
    assert_eq!(res.status(), StatusCode::OK);
    let e: Value = res.json().await.unwrap();
    // Keys come back in model order whatever the request's order.
    let keys: Vec<&String> = e["fused"]["coefficients"]
        .as_object()
        .unwrap()
        .keys()
        .collect();
    assert_eq!(keys, ["k0", "ki", "kp"]);
    // NOTES §5, to the printed digits (half a unit of the last digit).
    let printed = [
        ("mean", "coefficients", "k0", -0.84905e-3, 0.5e-8),
        ("mean", "coefficients", "ki", -1.2161464035, 0.5e-10),
        ("mean", "coefficients", "kp", 0.0062108047, 0.5e-10),
        ("fused", "coefficients", "k0", -0.8449266e-3, 0.5e-10),
        ("fused", "coefficients", "ki", -1.2161479119, 0.5e-10),
        ("fused", "coefficients", "kp", 0.0062738448, 0.5e-10),
        ("fused", "std_errors", "k0", 5.5745e-6, 0.5e-10),
        ("fused", "std_errors", "ki", 2.8651e-5, 0.5e-9),
        ("fused", "std_errors", "kp", 6.3639e-6, 0.5e-10),
        ("mean", "dispersion", "k0", 1.9747e-5, 0.5e-9),
        ("mean", "relative_dispersion", "ki", 5.3216e-5, 0.5e-9),
        ("mean", "dispersion", "kp", 8.6799e-5, 0.5e-9),
        ("fused", "dispersion", "k0", 2.0257e-5, 0.5e-9),
        ("fused", "relative_dispersion", "ki", 5.3233e-5, 0.5e-9),
        ("fused", "dispersion", "kp", 1.1092e-4, 0.5e-8),
    ];
    for (estimate, part, term, want, half_unit) in printed {
        close(&e[estimate][part][term], want, half_unit);
    }
    // And beyond the printed digits, against the independent computation.
    let t2 = &reference()["table2"];
    for t in ["k0", "ki", "kp"] {
        near(&e["mean"]["coefficients"][t], &t2["mean"][t], 1e-12);
        near(&e["fused"]["coefficients"][t], &t2["fused"][t], 1e-12);
        near(
            &e["fused"]["std_errors"][t],
            &t2["fused_std_error"][t],
            1e-9,
        );
        near(&e["mean"]["dispersion"][t], &t2["mean_dispersion"][t], 1e-9);
        near(
            &e["fused"]["dispersion"][t],
            &t2["fused_dispersion"][t],
            1e-9,
        );
    }
}

/// The whole documents a client reads after submitting the paper's Table 1,
/// as snapshots (`tests/api/snapshots/`): the result, the sensor, its
/// coefficients, and the problem a misspelt field gets. Ids and times of
/// receipt are redacted; every number is kept to its last digit, and both
/// engines must answer the same snapshot.
#[rstest]
#[tokio::test]
async fn the_paper_documents_are_their_snapshots(#[values(Sqlite, Postgres)] engine: Engine) {
    let app = TestApp::spawn(engine).await;
    let result = app.submit(ADMIN, &paper()).await;
    insta::assert_json_snapshot!("paper_result", result, {
        ".id" => "[id]",
        ".received_at" => "[received_at]",
    });
    let sensor = app.get_json("/v1/sensors/PAPER-2005", ADMIN).await;
    insta::assert_json_snapshot!("paper_sensor", sensor, {
        ".latest.id" => "[id]",
        ".latest.received_at" => "[received_at]",
    });
    let coefficients = app
        .get_json("/v1/sensors/PAPER-2005/coefficients", ADMIN)
        .await;
    insta::assert_json_snapshot!("paper_coefficients", coefficients, {
        ".calibration_id" => "[id]",
    });
    let mut misspelt = paper();
    misspelt["batchs"] = json!(2);
    let res = app.post("/v1/calibrations", ADMIN, &misspelt).await;
    let problem = problem(res, StatusCode::UNPROCESSABLE_ENTITY).await;
    insta::assert_json_snapshot!("misspelt_field_problem", problem, {
        ".request_id" => "[request_id]",
    });
}
