//! A calibration stored by an older method, for the tests of reprocessing:
//! written to the store directly, its `ki` off by 1e-9 from what today's
//! core computes for the same body, so that reprocessing supersedes it.

use accelcal::domain::timestamp::Timestamp;
use accelcal_core::{Model, Term, TermMap};
use serde_json::Value;
use uuid::Uuid;

use accelcal_testkit::TestApp;

/// Stores `body` on `app`'s database as submitted by `submitted_by` (a
/// token id) on 2026-11-01, performed on 2005-08-01, with the numbers of
/// `truth` (what `/v1/identify` answers for it) but `ki` 1e-9 larger;
/// answers the record's id.
pub async fn store_by_an_older_method(
    app: &TestApp,
    body: &Value,
    truth: &Value,
    submitted_by: &str,
) -> Uuid {
    let terms = [Term::K0, Term::Ki, Term::Kp];
    let f = |v: &Value| v.as_f64().unwrap();
    let map = |m: &Value, bump: f64| {
        TermMap(
            terms
                .iter()
                .map(|t| {
                    let off = if *t == Term::Ki { bump } else { 0.0 };
                    (*t, f(&m[t.name()]) + off)
                })
                .collect(),
        )
    };
    let at = |s: &str| Timestamp::parse(s).unwrap();
    let store = accelcal::store::open(&app.db().url).await.unwrap();
    let id = Uuid::now_v7();
    store
        .insert_calibration(
            accelcal::store::NewCalibration {
                id,
                sensor_id: body["sensor_id"].as_str().unwrap().into(),
                station_id: None,
                performed_at: at("2005-08-01T00:00:00Z"),
                received_at: at("2026-11-01T00:00:00Z"),
                unit: truth["unit"].as_str().unwrap().into(),
                model: Model::new(terms.to_vec()).unwrap(),
                runs: 6,
                coefficients: map(&truth["fused"]["coefficients"], 1e-9),
                std_errors: map(&truth["fused"]["std_errors"], 0.0),
                result: bytes::Bytes::from(truth.to_string()),
                submission: bytes::Bytes::from(body.to_string()),
                content_type: "application/json".into(),
                submitted_by: submitted_by.into(),
                sensor_type: None,
                assigns_type: false,
                verdict: None,
                due_at: None,
                expanded: Some(TermMap(
                    terms
                        .iter()
                        .map(|t| (*t, f(&truth["uncertainty"]["terms"][t.name()]["expanded"])))
                        .collect(),
                )),
                triad: None,
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
    id
}
