//! Tests of [`super`].

use super::*;
use crate::domain::status::Status;

impl CalibrationSummary {
    /// A minimal summary for tests: sensor `sensor`, model `k0 + ki`, one
    /// run, performed and received at 2026-01-01, standard errors zero.
    pub(crate) fn for_test(id: u128, sensor: &str, k0: f64, ki: f64) -> Self {
        use accelcal_core::Term;
        let at = Timestamp::parse("2026-01-01T00:00:00Z").expect("a valid timestamp");
        Self {
            id: Uuid::from_u128(id),
            sensor_id: sensor.into(),
            station_id: None,
            performed_at: at,
            received_at: at,
            unit: "mA".into(),
            model: Model::new(vec![Term::K0, Term::Ki]).expect("a valid model"),
            runs: 1,
            coefficients: TermMap(vec![(Term::K0, k0), (Term::Ki, ki)]),
            std_errors: TermMap(vec![(Term::K0, 0.0), (Term::Ki, 0.0)]),
            sensor_type: None,
            verdict: None,
            due_at: None,
            expanded: None,
            triad: None,
            thermal: None,
            thermal_triad: None,
            state: State::Submitted,
        }
    }
}

impl SensorSummary {
    /// A sensor for tests: one calibration,
    /// [`CalibrationSummary::for_test`]`(7, sensor, 0.0, 1.0)`, untyped.
    pub(crate) fn for_test(sensor: &str) -> Self {
        let latest = CalibrationSummary::for_test(7, sensor, 0.0, 1.0);
        SensorSummary {
            sensor_id: sensor.into(),
            calibration_count: 1,
            first_performed_at: latest.performed_at,
            latest_performed_at: latest.performed_at,
            sensor_type: None,
            latest_verdict: None,
            due_at: None,
            status: Status::Unknown,
            latest,
        }
    }
}

fn ts(s: &str) -> Timestamp {
    Timestamp::parse(s).unwrap()
}

/// A calibration of `S` with id `id`, performed at `at`.
fn cal(id: u128, at: &str) -> CalibrationSummary {
    CalibrationSummary {
        performed_at: ts(at),
        ..CalibrationSummary::for_test(id, "S", 0.0, 1.0)
    }
}

/// The row names its latest calibration by id: the summary takes it
/// from the candidates, or there is none.
#[test]
fn a_rows_latest_is_the_candidate_it_names() {
    let row = SensorRow {
        sensor_id: "S".into(),
        calibration_count: 3,
        first_performed_at: ts("2026-01-01T00:00:00Z"),
        latest_performed_at: ts("2026-03-01T00:00:00Z"),
        latest_calibration_id: Uuid::from_u128(50),
        sensor_type: Some("A".into()),
        latest_verdict: Some(Verdict::Pass),
        due_at: Some(ts("2027-03-01T00:00:00Z")),
    };
    let (a, b) = (
        cal(49, "2026-03-01T00:00:00Z"),
        cal(50, "2026-03-01T00:00:00Z"),
    );
    let got = row.clone().summary([&a, &b]).unwrap();
    assert_eq!(got.latest, b);
    assert_eq!(
        (got.calibration_count, got.sensor_type.as_deref()),
        (3, Some("A"))
    );
    assert_eq!(got.latest_verdict, Some(Verdict::Pass));
    assert_eq!(got.status, Status::Unknown);
    assert_eq!(row.summary([&a]), None);
}

/// A stored record's summary carries every field the record has.
#[test]
fn a_new_calibrations_summary_is_its_fields() {
    let c = CalibrationSummary {
        station_id: Some("LAB".into()),
        sensor_type: Some("A".into()),
        verdict: Some(Verdict::Conditional),
        due_at: Some(ts("2027-01-01T00:00:00Z")),
        expanded: Some(TermMap(vec![])),
        received_at: ts("2026-01-02T00:00:00Z"),
        triad: Some(Box::new(elements())),
        thermal: None,
        thermal_triad: None,
        ..cal(9, "2026-01-01T00:00:00Z")
    };
    let n = NewCalibration {
        id: c.id,
        sensor_id: c.sensor_id.clone(),
        station_id: c.station_id.clone(),
        performed_at: c.performed_at,
        received_at: c.received_at,
        unit: c.unit.clone(),
        model: c.model.clone(),
        runs: c.runs,
        coefficients: c.coefficients.clone(),
        std_errors: c.std_errors.clone(),
        result: Bytes::from_static(b"{}"),
        submission: Bytes::from_static(b"{}"),
        content_type: "application/json".into(),
        submitted_by: "x".into(),
        sensor_type: c.sensor_type.clone(),
        assigns_type: true,
        verdict: c.verdict,
        due_at: c.due_at,
        expanded: c.expanded.clone(),
        triad: c.triad.clone(),
        thermal: c.thermal.clone(),
        thermal_triad: c.thermal_triad.clone(),
        standards: Vec::new(),
        fitted_from: Vec::new(),
    };
    assert_eq!(CalibrationSummary::from(&n), c);
    n.check().unwrap();
}

/// A triad with distinct numbers everywhere: `S = 2 I + small`,
/// `T` its stand-in, standard errors for `b` and `S`.
fn elements() -> TriadElements {
    TriadElements {
        method: "known_orientations".into(),
        b: [0.1, 0.2, 0.3],
        b_std_errors: Some([1e-3, 2e-3, 3e-3]),
        s: [[2.0, 0.01, 0.02], [0.03, 2.1, 0.04], [0.05, 0.06, 2.2]],
        s_std_errors: Some([[1e-4; 3]; 3]),
        t: [[0.5, 0.0, 0.0], [0.0, 0.47, 0.0], [0.0, 0.0, 0.45]],
        t_std_errors: None,
        b_expanded: None,
        s_expanded: None,
        s2: None,
        s2_std_errors: None,
        s2_expanded: None,
    }
}

/// Every stored number is named by axis, row then column, and the
/// standard errors present; any of them non-finite refuses the record.
#[test]
fn a_triads_numbers_are_named_and_must_be_finite() {
    let e = elements();
    let numbers = e.numbers();
    assert_eq!(numbers.len(), 3 + 9 + 9 + 3 + 9);
    let get = |name: &str| numbers.iter().find(|(n, _)| n == name).map(|(_, v)| *v);
    assert_eq!(get("b_y"), Some(0.2));
    assert_eq!(get("S_xy"), Some(0.01));
    assert_eq!(get("S_yx"), Some(0.03));
    assert_eq!(get("S_zy"), Some(0.06));
    assert_eq!(get("T_yy"), Some(0.47));
    assert_eq!(get("b_z_std_error"), Some(3e-3));
    assert_eq!(get("T_xx_std_error"), None);
    let elements = e.elements();
    assert_eq!(elements.len(), 21);
    let at = |k: usize| {
        let x = &elements[k];
        (x.name.as_str(), x.value, x.std_error, x.measured)
    };
    assert_eq!(at(1), ("b_y", 0.2, Some(2e-3), true));
    assert_eq!(at(3 + 7), ("S_zy", 0.06, Some(1e-4), true));
    assert_eq!(at(12 + 4), ("T_yy", 0.47, None, false));
    // From the gravity magnitude, S above the diagonal is the frame
    // convention's, not measured.
    let gravity = TriadElements {
        method: "gravity_magnitude".into(),
        ..e.clone()
    }
    .elements();
    let measured: Vec<&str> = gravity
        .iter()
        .filter(|x| x.measured)
        .map(|x| x.name.as_str())
        .collect();
    assert_eq!(
        measured,
        [
            "b_x", "b_y", "b_z", "S_xx", "S_yx", "S_yy", "S_zx", "S_zy", "S_zz"
        ]
    );
    let record = |triad: TriadElements| NewCalibration {
        triad: Some(Box::new(triad)),
        ..NewCalibration {
            id: Uuid::from_u128(1),
            sensor_id: "S".into(),
            station_id: None,
            performed_at: ts("2026-01-01T00:00:00Z"),
            received_at: ts("2026-01-01T00:00:00Z"),
            unit: "g".into(),
            model: Model::new(vec![accelcal_core::Term::K0]).unwrap(),
            runs: 1,
            coefficients: TermMap(vec![]),
            std_errors: TermMap(vec![]),
            result: Bytes::new(),
            submission: Bytes::new(),
            content_type: "application/json".into(),
            submitted_by: "x".into(),
            sensor_type: None,
            assigns_type: false,
            verdict: None,
            due_at: None,
            expanded: None,
            triad: None,
            thermal: None,
            thermal_triad: None,
            standards: Vec::new(),
            fitted_from: Vec::new(),
        }
    };
    record(e.clone()).check().unwrap();
    let mut bad = e.clone();
    bad.s[2][1] = f64::NAN;
    let err = record(bad).check().unwrap_err().to_string();
    assert!(err.contains("`S_zy` is NaN"), "{err}");
    let mut bad = e;
    bad.b_std_errors = Some([0.0, f64::INFINITY, 0.0]);
    let err = record(bad).check().unwrap_err().to_string();
    assert!(err.contains("`b_y_std_error` is inf"), "{err}");
}

/// The summary answers "the latest before" only when its latest
/// calibration (2026-01-01) was performed strictly before the bound, and
/// only on the basis its latest is kept on; otherwise the records must be
/// asked (`None`).
#[test]
fn a_summary_tells_the_previous_only_when_its_latest_is_earlier() {
    let s = SensorSummary::for_test("S");
    let later = ts("2026-01-01T00:00:01Z");
    assert_eq!(
        s.previous_before(later, Basis::NotRejected),
        Some(&s.latest)
    );
    assert_eq!(s.previous_before(later, Basis::ApprovedOnly), None);
    for not_after in ["2026-01-01T00:00:00Z", "2025-12-31T23:59:59Z"] {
        assert_eq!(s.previous_before(ts(not_after), Basis::NotRejected), None);
    }
}
