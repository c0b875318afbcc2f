//! Tests of [`super`].

use super::*;
use crate::domain::typed::{BodyError, from_json};
use serde_json::{Value, json};

fn now() -> Timestamp {
    Timestamp::parse("2026-11-25T00:00:00Z").unwrap()
}

fn stand() -> Value {
    json!({
        "kind": "tumble_stand",
        "description": "Two-axis dividing head, 0.1 arcsec encoder",
        "manufacturer": "Ideal Aerosmith",
        "model": "2102",
        "serial": "SN-4411",
        "certificate": {"number": "CAL-2026-0117", "issued_by": "National Metrology Lab", "calibrated_at": "2026-01-17T00:00:00Z"},
        "due_at": "2027-01-17T00:00:00Z",
        "angle_std_arcsec": 2.5,
        "traceability": "Angle traceable to the SI through NML's autocollimator (CAL-2026-0117)."
    })
}

fn check(body: &Value) -> Result<Standard, Vec<String>> {
    from_json::<StandardBody>(body.to_string().as_bytes())
        .map_err(|e| match e {
            BodyError::Invalid(i) => i,
            BodyError::Syntax(s) => panic!("{s}"),
        })
        .and_then(|b| b.check("STAND-1".into(), now()))
        .map_err(|i| i.errors.into_iter().map(|e| e.pointer).collect())
}

#[test]
fn a_stand_is_kept_as_given() {
    let s = check(&stand()).unwrap();
    assert_eq!(s.standard_id, "STAND-1");
    assert_eq!(s.kind, StandardKind::TumbleStand);
    assert_eq!(s.angle_std_arcsec, Some(2.5));
    assert_eq!(s.certificate.number, "CAL-2026-0117");
    assert_eq!(s.updated_at, now());
}

/// Each kind's parameter is required for it and refused for the others.
#[test]
fn a_kinds_parameters_are_its_own() {
    let mut no_angle = stand();
    no_angle.as_object_mut().unwrap().remove("angle_std_arcsec");
    assert_eq!(check(&no_angle).unwrap_err(), ["/angle_std_arcsec"]);
    let mut stray = stand();
    stray["gravity_rel_std"] = json!(1e-6);
    assert_eq!(check(&stray).unwrap_err(), ["/gravity_rel_std"]);
    let mut gravity = stand();
    gravity["kind"] = json!("gravity");
    gravity.as_object_mut().unwrap().remove("angle_std_arcsec");
    assert_eq!(
        check(&gravity).unwrap_err(),
        ["/gravity_m_s2", "/gravity_rel_std"]
    );
    gravity["gravity_m_s2"] = json!(9.80665);
    gravity["gravity_rel_std"] = json!(2e-7);
    assert_eq!(check(&gravity).unwrap().gravity_m_s2, Some(9.80665));
    let mut thermometer = gravity.clone();
    thermometer["kind"] = json!("thermometer");
    assert_eq!(
        check(&thermometer).unwrap_err(),
        ["/gravity_m_s2", "/gravity_rel_std", "/temperature_std_c"]
    );
    let mut reference = stand();
    reference["kind"] = json!("reference_accelerometer");
    reference
        .as_object_mut()
        .unwrap()
        .remove("angle_std_arcsec");
    assert!(check(&reference).is_ok());
}

fn at(s: &str) -> Timestamp {
    Timestamp::parse(s).unwrap()
}

/// A test may use a standard within a period of calibration, by its
/// certificate or an earlier one kept when a new one was written; not
/// before its first calibration, after its due date, or in a gap
/// between two certificates.
#[test]
fn a_standard_is_in_calibration_between_its_certificates_dates() {
    let first = check(&stand()).unwrap();
    assert!(first.in_calibration_at(at("2026-06-01T00:00:00Z")).is_ok());
    assert!(first.in_calibration_at(at("2026-01-17T00:00:00Z")).is_ok());
    assert!(first.in_calibration_at(at("2027-01-17T00:00:00Z")).is_ok());
    let early = first
        .in_calibration_at(at("2026-01-16T23:59:59Z"))
        .unwrap_err();
    assert!(early.contains("first calibrated on"), "{early}");
    let late = first
        .in_calibration_at(at("2027-01-17T00:00:01Z"))
        .unwrap_err();
    assert!(
        late.contains("was due on") && late.contains("CAL-2026-0117"),
        "{late}"
    );

    // Recalibrated late: a month out of calibration, then a new
    // certificate. The old period still holds; the gap does not.
    let mut body = stand();
    body["certificate"]["number"] = json!("CAL-2027-0200");
    body["certificate"]["calibrated_at"] = json!("2027-02-17T00:00:00Z");
    body["due_at"] = json!("2028-02-17T00:00:00Z");
    let now = at("2027-02-18T00:00:00Z");
    let second = from_json::<StandardBody>(body.to_string().as_bytes())
        .unwrap()
        .check("STAND-1".into(), now)
        .unwrap()
        .replacing(Some(first.clone()));
    assert_eq!(second.earlier.len(), 1);
    assert_eq!(
        second
            .in_calibration_at(at("2026-06-01T00:00:00Z"))
            .unwrap()
            .certificate
            .number,
        "CAL-2026-0117"
    );
    assert_eq!(
        second
            .in_calibration_at(at("2027-06-01T00:00:00Z"))
            .unwrap()
            .certificate
            .number,
        "CAL-2027-0200"
    );
    let gap = second
        .in_calibration_at(at("2027-02-01T00:00:00Z"))
        .unwrap_err();
    assert!(gap.contains("between the due date"), "{gap}");
    // Written again with the same certificate (a corrected serial):
    // nothing joins the earlier ones.
    let again = second.clone().replacing(Some(second.clone()));
    assert_eq!(again.earlier, second.earlier);
}

/// A recalibration keeps the earlier certificate's parameters with it:
/// a test performed under the old certificate is budgeted with the old
/// parameters, one under the new with the new.
#[test]
fn each_certificate_keeps_its_own_parameters() {
    let mut old = stand();
    old["angle_std_arcsec"] = json!(60.0);
    old["degrees_of_freedom"] = json!(12);
    old["traceability"] = json!("old chain");
    let old = check(&old).unwrap();
    let mut body = stand();
    body["certificate"]["number"] = json!("CAL-NEW");
    body["certificate"]["calibrated_at"] = json!("2026-11-01T00:00:00Z");
    body["due_at"] = json!("2027-11-01T00:00:00Z");
    body["angle_std_arcsec"] = json!(0.5);
    let new = from_json::<StandardBody>(body.to_string().as_bytes())
        .unwrap()
        .check("STAND-1".into(), at("2026-11-20T00:00:00Z"))
        .unwrap()
        .replacing(Some(old));
    let under_old = new.used_as("stand", at("2026-06-01T00:00:00Z")).unwrap();
    assert_eq!(
        (
            under_old.certificate.number.as_str(),
            under_old.parameters.angle_std_arcsec,
            under_old.parameters.degrees_of_freedom,
            under_old.parameters.traceability.as_str(),
            under_old.parameters_assumed
        ),
        ("CAL-2026-0117", Some(60.0), Some(12.0), "old chain", false)
    );
    let under_new = new.used_as("stand", at("2026-11-10T00:00:00Z")).unwrap();
    assert_eq!(
        (
            under_new.certificate.number.as_str(),
            under_new.parameters.angle_std_arcsec,
            under_new.parameters.degrees_of_freedom
        ),
        ("CAL-NEW", Some(0.5), None)
    );
    // Stored and read back, the same.
    let back: Standard = serde_json::from_str(&serde_json::to_string(&new).unwrap()).unwrap();
    assert_eq!(back, new);
}

/// A standard stored before parameters were kept by certificate: its
/// earlier certificates take today's parameters, and say so.
#[test]
fn an_earlier_certificate_without_parameters_takes_todays_and_says_so() {
    let legacy = r#"{"standard_id": "S", "kind": "tumble_stand", "description": "d",
        "manufacturer": null, "model": null, "serial": null,
        "certificate": {"number": "NEW", "issued_by": "L", "calibrated_at": "2026-06-01T00:00:00Z"},
        "due_at": "2027-06-01T00:00:00Z", "angle_std_arcsec": 0.5, "gravity_m_s2": null,
        "gravity_rel_std": null, "temperature_std_c": null, "traceability": "today's chain",
        "earlier": [{"certificate": {"number": "OLD", "issued_by": "L", "calibrated_at": "2025-06-01T00:00:00Z"},
                     "due_at": "2026-06-01T00:00:00Z"}],
        "updated_at": "2026-06-01T00:00:00Z"}"#;
    let s: Standard = serde_json::from_str(legacy).unwrap();
    let old = &s.earlier[0];
    assert!(old.parameters_assumed);
    assert_eq!(old.parameters, s.parameters());
    let used = s.used_as("stand", at("2025-09-01T00:00:00Z")).unwrap();
    assert!(used.parameters_assumed);
    assert_eq!(used.parameters.angle_std_arcsec, Some(0.5));
    let v = serde_json::to_value(&s).unwrap();
    assert_eq!(v["earlier"][0]["parameters_assumed"], true);
    assert_eq!(v["earlier"][0]["traceability"], "today's chain");
}

#[test]
fn degrees_of_freedom_are_a_count() {
    for (nu, ok) in [
        (json!(1), true),
        (json!(30.5), true),
        (json!(0.5), false),
        (json!(2e6), false),
    ] {
        let mut b = stand();
        b["degrees_of_freedom"] = nu.clone();
        assert_eq!(check(&b).is_ok(), ok, "{nu}");
    }
}

/// Ranges, dates and text are checked, each problem named.
#[test]
fn values_out_of_range_and_impossible_dates_are_named() {
    let mut bad = stand();
    bad["angle_std_arcsec"] = json!(-1);
    bad["due_at"] = json!("2026-01-17T00:00:00Z");
    bad["certificate"]["calibrated_at"] = json!("2026-01-17T00:00:00Z");
    bad["serial"] = json!("a\u{7}");
    bad["traceability"] = json!("");
    assert_eq!(
        check(&bad).unwrap_err(),
        ["/serial", "/traceability", "/due_at", "/angle_std_arcsec"]
    );
    let mut future = stand();
    future["certificate"]["calibrated_at"] = json!("2026-12-01T00:00:00Z");
    future["due_at"] = json!("2027-12-01T00:00:00Z");
    assert_eq!(check(&future).unwrap_err(), ["/certificate/calibrated_at"]);
    let mut gravity = stand();
    gravity["kind"] = json!("gravity");
    gravity.as_object_mut().unwrap().remove("angle_std_arcsec");
    gravity["gravity_m_s2"] = json!(9.0);
    gravity["gravity_rel_std"] = json!(0.5);
    assert_eq!(
        check(&gravity).unwrap_err(),
        ["/gravity_m_s2", "/gravity_rel_std"]
    );
}
