//! The paper's submission end to end (NOTES §5 through the service).

use reqwest::StatusCode;
use serde_json::{Value, json};

use crate::helpers::*;

const TABLE2_ALPHA: [f64; 6] = [
    0.006091826,
    0.006149912,
    0.006163094,
    0.006287309,
    0.006297850,
    0.006274837,
];

fn check_paper_result(r: &Value) {
    let runs = r["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 6);
    for (run, alpha) in runs.iter().zip(TABLE2_ALPHA) {
        close(&run["coefficients"]["kp"], alpha, 1e-9);
        assert_eq!(run["dof"], 1);
    }
    // From Table 1 the per-run α are unrounded (test 4 differs from Table 2
    // by 4e-10, NOTES §5), so the across-run figures agree within 1e-9.
    close(&r["mean"]["coefficients"]["kp"], 0.0062108047, 1e-9);
    close(&r["fused"]["coefficients"]["kp"], 0.0062738448, 1e-9);
    close(&r["fused"]["std_errors"]["kp"], 6.3639e-6, 1e-9);
    close(&r["mean"]["dispersion"]["kp"], 8.6799e-5, 1e-9);
    close(&r["fused"]["dispersion"]["kp"], 1.1092e-4, 1e-8);
    assert_eq!(r["fused"]["batches"][0]["runs"], json!([0, 1, 2]));
    assert_eq!(r["fused"]["batches"][1]["runs"], json!([3, 4, 5]));
    assert_eq!(r["positions"][1]["a"], json!([-1.0, 0.0, 0.0]));
    close(&r["condition_number"], std::f64::consts::SQRT_2, 1e-12);
    let ki = r["fused"]["coefficients"]["ki"].as_f64().unwrap();
    let kp = r["fused"]["coefficients"]["kp"].as_f64().unwrap();
    close(&r["normalized"]["misalignment_p_rad"], kp / ki, 1e-15);
}

#[tokio::test]
async fn paper_submission_end_to_end() {
    let app = TestApp::spawn().await;
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

#[tokio::test]
async fn paper_table_as_csv_gives_the_same_numbers() {
    let app = TestApp::spawn().await;
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

#[tokio::test]
async fn table_2_fusion_over_http() {
    let app = TestApp::spawn().await;
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
    close(&e["mean"]["coefficients"]["k0"], -0.84905e-3, 5e-9);
    close(&e["mean"]["coefficients"]["ki"], -1.2161464035, 5e-11);
    close(&e["fused"]["coefficients"]["k0"], -0.8449266e-3, 5e-11);
    close(&e["fused"]["coefficients"]["ki"], -1.2161479119, 5e-11);
    close(&e["fused"]["std_errors"]["k0"], 5.5745e-6, 5e-11);
    close(&e["fused"]["std_errors"]["ki"], 2.8651e-5, 5e-10);
    close(&e["mean"]["dispersion"]["k0"], 1.9747e-5, 5e-10);
    close(&e["mean"]["relative_dispersion"]["ki"], 5.3216e-5, 5e-10);
    close(&e["fused"]["dispersion"]["k0"], 2.0257e-5, 5e-10);
    close(&e["fused"]["relative_dispersion"]["ki"], 5.3233e-5, 5e-10);
}
