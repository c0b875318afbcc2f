//! Parameters by certificate (issue 42 item 2): a test is budgeted with the
//! parameters of the certificate its standards were in calibration by when
//! it was performed — indexing error, gravity value and its uncertainty,
//! their degrees of freedom, traceability — whenever it is submitted; and
//! reprocessing a calibration made under an earlier certificate confirms it.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

fn stand(number: &str, calibrated: &str, due: &str, arcsec: f64, chain: &str) -> Value {
    json!({
        "kind": "tumble_stand",
        "description": "Two-axis dividing head",
        "serial": "SN-4411",
        "certificate": {"number": number, "issued_by": "National Metrology Laboratory", "calibrated_at": calibrated},
        "due_at": due,
        "angle_std_arcsec": arcsec,
        "traceability": chain,
    })
}

fn gravity(number: &str, calibrated: &str, g: f64, u: f64, dof: Option<u32>) -> Value {
    let mut v = json!({
        "kind": "gravity",
        "description": "Absolute gravity at the bench",
        "certificate": {"number": number, "issued_by": "Geodetic Survey", "calibrated_at": calibrated},
        "due_at": "2030-01-01T00:00:00Z",
        "gravity_m_s2": g,
        "gravity_rel_std": u,
        "traceability": format!("gravimeter survey {number}"),
    });
    if let Some(nu) = dof {
        v["degrees_of_freedom"] = json!(nu);
    }
    v
}

/// The paper's tumble on sensor `sensor`, performed at `at`, on the
/// registered stand and gravity value.
fn test_at(sensor: &str, at: &str) -> Value {
    let mut b: Value =
        serde_json::from_str(include_str!("../../examples/paper-table1.json")).unwrap();
    b["sensor_id"] = json!(sensor);
    b["performed_at"] = json!(at);
    b["standards"] = json!({"stand": "DH-1", "gravity": "G-1"});
    b
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

#[rstest]
#[tokio::test]
async fn a_late_test_is_budgeted_by_the_certificate_it_was_performed_under(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::spawn(engine).await;
    let put = |path: &'static str, body: Value| {
        let app = &app;
        async move {
            let res = app.put(path, ADMIN, &body).await;
            assert!(res.status().is_success(), "{}", res.text().await.unwrap());
        }
    };
    put(
        "/v1/standards/DH-1",
        stand(
            "CAL-OLD",
            "2025-01-01T00:00:00Z",
            "2026-12-31T00:00:00Z",
            60.0,
            "old chain",
        ),
    )
    .await;
    put(
        "/v1/standards/G-1",
        gravity("G-OLD", "2025-01-01T00:00:00Z", 9.80424, 3e-5, Some(8)),
    )
    .await;
    // On time, under the old certificates.
    let on_time = app
        .submit(ADMIN, &test_at("A", "2026-06-01T00:00:00Z"))
        .await;
    // Both recalibrated: a far better head, another gravity value.
    put(
        "/v1/standards/DH-1",
        stand(
            "CAL-NEW",
            "2026-11-01T00:00:00Z",
            "2027-11-01T00:00:00Z",
            0.5,
            "new chain",
        ),
    )
    .await;
    put(
        "/v1/standards/G-1",
        gravity("G-NEW", "2026-11-01T00:00:00Z", 9.80431, 2e-7, None),
    )
    .await;
    // Late, performed under the old ones: budgeted with them — the very
    // budget the on-time calibration has — and naming them.
    let late = app
        .submit(ADMIN, &test_at("B", "2026-06-02T00:00:00Z"))
        .await;
    for term in ["k0", "ki", "kp"] {
        let (a, b) = (
            &on_time["uncertainty"]["terms"][term],
            &late["uncertainty"]["terms"][term],
        );
        assert_eq!(a, b, "{term}: the old certificate's budget");
    }
    let used = |r: &Value, role: &str| {
        r["standards"]
            .as_array()
            .unwrap()
            .iter()
            .find(|u| u["role"] == role)
            .unwrap()
            .clone()
    };
    let stand_used = used(&late, "stand");
    assert_eq!(stand_used["certificate"]["number"], "CAL-OLD");
    assert_eq!(stand_used["angle_std_arcsec"], 60.0);
    assert_eq!(stand_used["traceability"], "old chain");
    let g_used = used(&late, "gravity");
    assert_eq!(g_used["certificate"]["number"], "G-OLD");
    assert_eq!(
        (f(&g_used["gravity_m_s2"]), f(&g_used["gravity_rel_std"])),
        (9.80424, 3e-5)
    );
    assert_eq!(g_used["degrees_of_freedom"], 8.0);
    assert_eq!(late["stand"]["angle_std_arcsec"], 60.0);
    assert_eq!(late["stand"]["gravity_dof"], 8.0);
    // The 60″ head: kp's U is the indexing's, two orders above 0.5″'s.
    let kp_late = f(&late["uncertainty"]["terms"]["kp"]["expanded"]);
    assert!(kp_late > 4e-4, "{kp_late}");
    // The gravity component rests on the certificate's 8 degrees of
    // freedom: ki's (a scale term) Welch–Satterthwaite with it.
    let ki = &late["uncertainty"]["terms"]["ki"];
    assert_eq!(ki["degrees_of_freedom"]["gravity"], 8.0);
    let nu = |u: f64, n: f64| u.powi(4) / n;
    let comps = [
        (
            f(&ki["statistical"]),
            f(&ki["degrees_of_freedom"]["statistical"]),
        ),
        (f(&ki["gravity"]), 8.0),
        (f(&ki["model"]), f(&ki["degrees_of_freedom"]["model"])),
    ];
    let by_hand = (f(&ki["combined"]).powi(4)
        / comps
            .iter()
            .filter(|(u, _)| *u > 0.0)
            .map(|(u, n)| nu(*u, *n))
            .sum::<f64>())
    .floor();
    assert_eq!(f(&ki["effective_dof"]), by_hand);

    // Under the new certificates: the new parameters.
    let new = app
        .submit(ADMIN, &test_at("C", "2026-11-10T00:00:00Z"))
        .await;
    assert_eq!(used(&new, "stand")["certificate"]["number"], "CAL-NEW");
    assert_eq!(used(&new, "stand")["angle_std_arcsec"], 0.5);
    let kp_new = f(&new["uncertainty"]["terms"]["kp"]["expanded"]);
    assert!(kp_new < kp_late / 10.0, "{kp_new} vs {kp_late}");

    // Reprocessing the on-time calibration uses the same certificates:
    // every number the same, confirmed.
    let reviewer = app.token("reviewer", None).await;
    let res = app
        .post(
            &format!(
                "/v1/calibrations/{}/reprocess",
                on_time["id"].as_str().unwrap()
            ),
            &reviewer,
            &json!({}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let r: Value = res.json().await.unwrap();
    assert_eq!(r["outcome"], "confirmed", "{r}");

    // The standard lists each certificate with its own parameters.
    let s = app.get_json("/v1/standards/DH-1", ADMIN).await;
    assert_eq!(s["angle_std_arcsec"], 0.5);
    assert_eq!(s["earlier"][0]["certificate"]["number"], "CAL-OLD");
    assert_eq!(s["earlier"][0]["angle_std_arcsec"], 60.0);
    assert_eq!(s["earlier"][0]["traceability"], "old chain");
    assert!(s["earlier"][0].get("parameters_assumed").is_none());
}
