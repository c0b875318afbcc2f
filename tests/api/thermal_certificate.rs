//! A temperature model's certificate and DCC (issue 45 item 4), on both
//! engines: approved, its certificate is issued like any other — the
//! printed one lists every polynomial's `a_d` with its uncertainty, the
//! set points' table and the decision; the DCC states each `a_d` as an
//! `si:real` in the coefficient's unit per K^d, its expanded uncertainty
//! with `k` as the GUM's table of Student's t gives it for the
//! polynomial's `ν` at 95.45 % (when the Birge ratio inflated its
//! covariance; 2 otherwise), and the valid range and `T_ref` as the influence condition.

use reqwest::StatusCode;
use rstest::rstest;
use serde_json::{Value, json};

use accelcal::domain::timestamp::Timestamp;
use accelcal_testkit::Engine::{Postgres, Sqlite};
use accelcal_testkit::*;

use crate::thermal::{CHAMBER, body, f};

const SI: &str = "https://ptb.de/si";

/// `k` at 95.45 % for `ν` degrees of freedom: GUM (JCGM 100:2008) table
/// G.2, its `p = 95.45 %` column.
fn gum_k(dof: Option<u64>) -> f64 {
    match dof {
        Some(1) => 13.97,
        Some(2) => 4.53,
        Some(3) => 3.31,
        Some(4) => 2.87,
        Some(5) => 2.65,
        Some(n) => panic!("no table entry used for ν = {n}"),
        None => 2.00,
    }
}

/// The text of `name` (D-SI's namespace) under `node`.
fn si<'a>(node: roxmltree::Node<'a, 'a>, name: &str) -> &'a str {
    node.descendants()
        .find(|n| n.tag_name().namespace() == Some(SI) && n.tag_name().name() == name)
        .and_then(|n| n.text())
        .unwrap_or_else(|| panic!("no si:{name}"))
}

#[rstest]
#[tokio::test]
async fn an_approved_model_is_certified_with_its_polynomials(
    #[values(Sqlite, Postgres)] engine: Engine,
) {
    let app = TestApp::configured(engine, crate::dcc::lab).await;
    let rita = app.held_token("reviewer", "Rita Reviewer", None).await;
    app.put(
        "/v1/customers/ACME",
        ADMIN,
        &json!({"name": "Acme Navigation GmbH", "due_date_agreed": true}),
    )
    .await;
    app.put(
        "/v1/sensors/MEMS-T/item",
        ADMIN,
        &json!({"manufacturer": "ST", "model": "LIS", "serial": "SN-T", "customer": "ACME"}),
    )
    .await;
    let res = app
        .put(
            "/v1/sensor-types/CHAMBER",
            ADMIN,
            &json!({"unit": "V", "decision_rule": "guarded", "interval_days": 180,
                    "limits": {"k0": {"max": 5e-3}, "ki": {"min": -1.21, "max": -1.19}}}),
        )
        .await;
    assert!(res.status().is_success());
    let thermometer = json!({"kind": "thermometer", "description": "PRT in the chamber",
        "certificate": {"number": "T-9", "issued_by": "NML",
            "calibrated_at": Timestamp::now().plus_seconds(-100 * 86_400).to_string()},
        "due_at": Timestamp::now().plus_seconds(200 * 86_400).to_string(),
        "temperature_std_c": 0.05, "traceability": "NML temperature chain"});
    app.put("/v1/standards/TH-1", ADMIN, &thermometer).await;
    let mut stand = thermometer.clone();
    let stand = stand.as_object_mut().unwrap();
    stand.remove("temperature_std_c");
    stand.insert("kind".into(), json!("tumble_stand"));
    stand.insert("angle_std_arcsec".into(), json!(2.0));
    app.put("/v1/standards/DH-1", ADMIN, &json!(stand)).await;
    let mut b = body(&CHAMBER);
    b["sensor_type"] = json!("CHAMBER");
    b["standards"] = json!({"stand": "DH-1", "thermometer": "TH-1"});
    let res = app.post("/v1/calibrations/thermal", ADMIN, &b).await;
    let status = res.status();
    let stored: Value = res.json().await.unwrap();
    assert_eq!(status, StatusCode::CREATED, "{stored}");
    assert_eq!(stored["decision"]["verdict"], "pass");
    // A type that states no coverage: 95.45 %, for the decision and the
    // certificate alike.
    assert_eq!(stored["coverage"], json!({"probability": 0.9545}));
    let id = stored["id"].as_str().unwrap().to_owned();
    let res = app
        .post(
            &format!("/v1/calibrations/{id}/review"),
            &rita,
            &json!({"decision": "approve"}),
        )
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let model = &stored["thermal"];

    // The printed certificate: a row per a_d, nothing past each degree.
    let res = app
        .get(&format!("/v1/calibrations/{id}/certificate"), ADMIN)
        .await;
    assert_eq!(res.status(), StatusCode::OK);
    let html = res.text().await.unwrap();
    for part in [
        "thermal-set-points",
        "thermal-decision",
        "Valid from",
        "u_T = 0.05 K",
        "MEMS-T (temperature model)",
    ] {
        assert!(html.contains(part), "{part}");
    }
    let mut labels = Vec::new();
    for (term, p) in model["coefficients"].as_object().unwrap() {
        let degree = p["degree"].as_u64().unwrap();
        for d in 0..=3 {
            let row = format!("data-term=\"{term}_a{d}\"");
            assert_eq!(html.contains(&row), d <= degree, "{row}");
        }
        labels.extend((0..=degree).map(|d| (term.clone(), d)));
    }
    assert_eq!(labels.len(), 3 + 2 + 1, "k0 of degree 2, ki 1, kp 0");

    // The DCC: each a_d in its unit per K^d, rounded to U, with k from the
    // GUM's table.
    let res = crate::dcc::dcc(&app, &id, ADMIN).await;
    assert_eq!(res.status(), StatusCode::OK);
    let xml = res.text().await.unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let reals: Vec<roxmltree::Node> = doc
        .descendants()
        .filter(|n| n.tag_name().namespace() == Some(SI) && n.tag_name().name() == "real")
        .collect();
    for (term, d) in &labels {
        let p = &model["coefficients"][term];
        let label = format!("{term}_a{d}");
        let real = reals
            .iter()
            .find(|r| si(**r, "label") == label)
            .unwrap_or_else(|| panic!("no si:real {label}"));
        let unit = match d {
            0 => r"\volt".to_owned(),
            d => format!(r"\volt\kelvin\tothe{{-{d}}}"),
        };
        assert_eq!(si(*real, "unit"), unit, "{label}");
        let inflated = f(&p["inflation"]) > 1.0;
        let k = gum_k(inflated.then(|| p["dof"].as_u64().unwrap()));
        let written_k: f64 = si(*real, "coverageFactor").parse().unwrap();
        assert!(
            (written_k - k).abs() <= 0.01,
            "{label}: k {written_k} against {k}"
        );
        let u = f(&p["std_uncertainties"][*d as usize]);
        let big_u: f64 = si(*real, "valueExpandedMU").parse().unwrap();
        assert!(
            (big_u - k * u).abs() <= 0.05 * k * u,
            "{label}: U {big_u} against {}",
            k * u
        );
        let a = f(&p["coefficients"][*d as usize]);
        let value: f64 = si(*real, "value").parse().unwrap();
        assert!(
            (value - a).abs() <= big_u / 20.0,
            "{label}: {value} against {a}"
        );
    }
    // The influence condition: the range and T_ref, the thermometer's u.
    let condition = |label: &str| {
        let real = reals
            .iter()
            .find(|r| si(**r, "label") == label)
            .unwrap_or_else(|| panic!("no {label}"));
        (
            si(*real, "value").parse::<f64>().unwrap(),
            si(*real, "unit").to_owned(),
        )
    };
    let range = &stored["range_c"];
    assert_eq!(
        condition("temperature_min"),
        (f(&range[0]), r"\degreecelsius".to_owned())
    );
    assert_eq!(condition("temperature_max").0, f(&range[1]));
    assert_eq!(condition("temperature_ref").0, 20.0);
    assert!(xml.contains("Temperature range of the model"));
    assert!(xml.contains("Statement of conformity"));
    // Issued: the same bytes again.
    let again = crate::dcc::dcc(&app, &id, ADMIN).await;
    assert_eq!(again.text().await.unwrap(), xml);
}
