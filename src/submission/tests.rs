//! Unit tests of submission checking: every refusal names its field.

use serde_json::{Value, json};

use super::*;

fn paper() -> Value {
    serde_json::from_str(include_str!("../../examples/paper-table1.json")).unwrap()
}

fn now() -> Timestamp {
    Timestamp::parse("2026-11-22T00:00:00Z").unwrap()
}

fn pointers(body: &Value) -> Vec<String> {
    match evaluate(body, now()) {
        Ok(_) => vec![],
        Err(errors) => errors.into_iter().map(|e| e.pointer).collect(),
    }
}

#[test]
fn paper_submission_calibrates() {
    let e = evaluate(&paper(), now()).unwrap();
    assert_eq!(e.calibration.runs.len(), 6);
    let alpha = e.calibration.fused.coefficients.get(Term::Kp).unwrap();
    assert!((alpha - 0.006_273_844_8).abs() < 1e-9, "{alpha}");
}

#[test]
fn every_problem_is_reported_with_its_pointer() {
    let mut b = paper();
    b["batchs"] = json!(2);
    b["sensor_id"] = json!("bad id");
    b["unit"] = json!("");
    b["model"] = json!(["k0", "K1", "k0"]);
    b["runs"][2]["readings"][1] = json!([]);
    b["runs"][3]["readings"][0][1] = json!("1.2");
    b["positions"][1] = json!({"a": [0, 0, 0]});
    assert_eq!(
        pointers(&b),
        [
            "/batchs",
            "/sensor_id",
            "/unit",
            "/model/1",
            "/model/2",
            "/positions/1/a",
            "/runs/2/readings/1",
            "/runs/3/readings/0/1"
        ]
    );
}

#[test]
fn required_fields_and_shapes() {
    assert_eq!(pointers(&json!({})), ["/sensor_id", "/positions", "/runs"]);
    assert_eq!(pointers(&json!([])), [""]);
    let mut b = paper();
    b["runs"][1]["readings"] = json!([[1.0], [2.0], [3.0]]);
    assert_eq!(pointers(&b), ["/runs/1/readings"]);
    let mut b = paper();
    b["positions"][0] = json!({"label": "no angle"});
    assert_eq!(pointers(&b), ["/positions/0"]);
    let mut b = paper();
    b["positions"][0] = json!({"angle_deg": 0, "a": [1, 0, 0]});
    assert_eq!(pointers(&b), ["/positions/0/a"]);
}

#[test]
fn unidentifiable_model_names_its_terms() {
    let mut b = paper();
    b["model"] = json!(["k0", "ki", "kp", "kiii"]);
    let errors = evaluate(&b, now()).unwrap_err();
    assert_eq!(errors[0].pointer, "/model");
    assert!(
        errors[0].detail.contains("ki, kiii"),
        "{}",
        errors[0].detail
    );
}

#[test]
fn fusion_refusals_point_at_batches() {
    let mut b = paper();
    b["batches"] = json!(4);
    let errors = evaluate(&b, now()).unwrap_err();
    assert_eq!(errors[0].pointer, "/batches");
    assert!(errors[0].detail.contains("batch 2"), "{}", errors[0].detail);
    b["batches"] = json!(0);
    assert_eq!(pointers(&b), ["/batches"]);
}

#[test]
fn future_and_malformed_times_are_refused() {
    let mut b = paper();
    b["performed_at"] = json!("2026-11-24T00:00:00Z");
    assert_eq!(pointers(&b), ["/performed_at"]);
    b["performed_at"] = json!("20 Nov 2026");
    assert_eq!(pointers(&b), ["/performed_at"]);
    b["performed_at"] = json!("1969-12-31T23:59:59Z");
    assert_eq!(pointers(&b), ["/performed_at"]);
    b["performed_at"] = json!("2026-11-22T12:00:00+02:00");
    assert!(pointers(&b).is_empty());
}
