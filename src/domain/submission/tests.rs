//! Unit tests of submission checking: every refusal names its field.

use accelcal_core::Term;
use serde_json::{Value, json};

use super::*;

fn paper() -> Value {
    serde_json::from_str(include_str!("../../../examples/paper-table1.json")).unwrap()
}

fn now() -> Timestamp {
    Timestamp::parse("2026-11-22T00:00:00Z").unwrap()
}

fn run(body: &Value) -> Result<Evaluated, Refused> {
    evaluate(Media::Json, &serde_json::to_vec(body).unwrap(), now())
}

fn pointers(body: &Value) -> Vec<String> {
    match run(body) {
        Ok(_) => vec![],
        Err(Refused::Invalid(i)) => i.errors.into_iter().map(|e| e.pointer).collect(),
        Err(other) => panic!("{other:?}"),
    }
}

#[test]
fn paper_submission_calibrates() {
    let e = run(&paper()).unwrap();
    assert_eq!(e.calibration.runs.len(), 6);
    let alpha = e.calibration.fused.coefficients.get(Term::Kp).unwrap();
    assert!((alpha - 0.006_273_844_8).abs() < 1e-9, "{alpha}");
}

#[test]
fn every_problem_is_reported_with_its_pointer_in_document_order() {
    let mut b = paper();
    b["batchs"] = json!(2);
    b["sensor_id"] = json!("bad id");
    b["unit"] = json!("");
    b["model"] = json!(["k0", "K1", "k0"]);
    b["runs"][2]["readings"][1] = json!([]);
    b["runs"][3]["readings"][0][1] = json!("1.2");
    b["positions"][1] = json!({"a": [0, 0, 0]});
    // serde_json's map keeps keys sorted: batches, batchs, model, notes?,
    // performed_at, positions, runs, sensor_id, unit.
    assert_eq!(
        pointers(&b),
        [
            "/batchs",
            "/model/1",
            "/model/2",
            "/positions/1/a",
            "/runs/2/readings/1",
            "/runs/3/readings/0/1",
            "/sensor_id",
            "/unit",
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
    let Err(Refused::Invalid(i)) = run(&b) else {
        panic!()
    };
    assert_eq!(i.errors[0].pointer, "/model");
    assert!(
        i.errors[0].detail.contains("ki, kiii"),
        "{}",
        i.errors[0].detail
    );
}

#[test]
fn fusion_refusals_point_at_batches() {
    let mut b = paper();
    b["batches"] = json!(4);
    let Err(Refused::Invalid(i)) = run(&b) else {
        panic!()
    };
    assert_eq!(i.errors[0].pointer, "/batches");
    assert!(
        i.errors[0].detail.contains("batch 2"),
        "{}",
        i.errors[0].detail
    );
    // Six runs: at most three batches, which the message says.
    assert!(
        i.errors[0]
            .detail
            .ends_with("submit at least 8 runs, or ask for at most 3 batches"),
        "{}",
        i.errors[0].detail
    );
    b["batches"] = json!(0);
    assert_eq!(pointers(&b), ["/batches"]);
    // Three runs in the default two batches: one batch is what is possible.
    let mut b = paper();
    b["runs"] = json!(b["runs"].as_array().unwrap()[..3]);
    b.as_object_mut().unwrap().remove("batches");
    let Err(Refused::Invalid(i)) = run(&b) else {
        panic!()
    };
    assert!(
        i.errors[0].detail.ends_with("or ask for at most 1 batch"),
        "{}",
        i.errors[0].detail
    );
}

/// One run is a valid submission: its own estimate, whatever `batches`
/// says; with no spare position it is refused at `/runs`.
#[test]
fn a_single_run_is_a_submission() {
    let mut b = paper();
    b["runs"] = json!([b["runs"][0]]);
    let e = run(&b).unwrap();
    assert_eq!(e.calibration.runs.len(), 1);
    assert_eq!(
        e.calibration.fused.coefficients,
        e.calibration.runs[0].coefficients
    );
    assert!(e.calibration.fused.dispersion.is_none());
    b["model"] = json!(["k0", "ki", "kp", "kii"]);
    let Err(Refused::Invalid(i)) = run(&b) else {
        panic!()
    };
    assert_eq!(i.errors[0].pointer, "/runs");
    assert!(
        i.errors[0].detail.contains("fits exactly"),
        "{}",
        i.errors[0].detail
    );
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
    // Six minutes ahead of the clock: past the five forgiven.
    b["performed_at"] = json!("2026-11-22T02:06:00+02:00");
    assert_eq!(pointers(&b), ["/performed_at"]);
    // Four minutes ahead: forgiven, and recorded as the time received.
    b["performed_at"] = json!("2026-11-22T02:04:00+02:00");
    let e = run(&b).unwrap();
    assert_eq!(e.submission.performed_at, Some(now()));
    // In the past: kept as sent.
    b["performed_at"] = json!("2026-11-21T23:00:00+02:00");
    let e = run(&b).unwrap();
    assert_eq!(
        e.submission.performed_at,
        Some(Timestamp::parse("2026-11-21T21:00:00Z").unwrap())
    );
}

#[test]
fn two_million_wrong_samples_give_a_hundred_errors_and_a_count() {
    // 360 positions × 6 runs × 1000 `""` samples (the attack of finding 3,
    // past the 2 000 000 samples a submission may hold).
    let positions: Vec<Value> = (0..360).map(|k| json!({"angle_deg": k})).collect();
    let samples = format!("[{}]", vec!["\"\""; 1000].join(","));
    let readings = format!("[{}]", vec![samples.as_str(); 360].join(","));
    let runs = format!(
        "[{}]",
        vec![format!("{{\"readings\": {readings}}}"); 6].join(",")
    );
    let body = format!(
        "{{\"sensor_id\": \"A\", \"positions\": {}, \"runs\": {runs}}}",
        serde_json::to_string(&positions).unwrap()
    );
    let Err(Refused::Invalid(i)) = evaluate(Media::Json, body.as_bytes(), now()) else {
        panic!()
    };
    assert_eq!(i.errors.len(), 100);
    // Every sample is wrong, and so is their total (beyond 2 000 000).
    assert_eq!(i.count(), 360 * 6 * 1000 + 1);
}

#[test]
fn csv_and_json_forms_calibrate_alike() {
    let csv = format!(
        "# sensor_id: PAPER-2005\n# model: k0 ki kp\n# batches: 2\n{}",
        include_str!("../../../core/tests/data/table1.csv")
    );
    let from_csv = evaluate(Media::Csv, csv.as_bytes(), now()).unwrap();
    let from_json = run(&paper()).unwrap();
    assert_eq!(from_csv.calibration.fused, from_json.calibration.fused);
}

/// The paper as a station averaging on board sends it
/// (`examples/paper-summaries.csv`: each run's cw and ccw as mean, standard
/// deviation and count, computed by Python's `statistics`) calibrates as its
/// samples do, to the paper's printed digits.
#[test]
fn the_paper_as_summaries_calibrates_as_its_samples() {
    let from_summaries = evaluate(
        Media::Csv,
        include_bytes!("../../../examples/paper-summaries.csv"),
        now(),
    )
    .unwrap();
    let from_samples = run(&paper()).unwrap();
    let (a, b) = (
        &from_summaries.calibration.fused,
        &from_samples.calibration.fused,
    );
    for (term, x) in b.coefficients.iter() {
        let y = a.coefficients[term];
        assert!((x - y).abs() <= 1e-12 * x.abs(), "{term:?}: {x:e} vs {y:e}");
        let (sx, sy) = (b.std_errors[term], a.std_errors[term]);
        assert!((sx - sy).abs() <= 1e-9 * sx, "{term:?}: {sx:e} vs {sy:e}");
    }
    assert!((a.coefficients[Term::Ki] + 1.216154046).abs() < 5e-10);
}

#[test]
fn numbers_are_finite_and_within_their_bound() {
    use node::Scalar;
    assert_eq!(Scalar::Num(2.0, None).number(2.0), Ok(2.0));
    assert_eq!(Scalar::Num(-2.0, None).number(2.0), Ok(-2.0));
    for x in [
        2.000_001,
        -2.000_001,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
    ] {
        assert_eq!(
            Scalar::Num(x, None).number(2.0),
            Err("must be a finite number of magnitude at most 2e0".to_owned()),
            "{x}"
        );
    }
    assert!(Scalar::Num(f64::INFINITY, None).number(f64::MAX).is_err());
    assert_eq!(
        Scalar::Str("1".into()).number(2.0),
        Err("must be a number, not a string".to_owned())
    );
}

/// 1970 is the first year accepted: its first second passes, the last
/// second of 1969 is named.
#[test]
fn the_test_may_be_performed_from_1970_on() {
    let mut b = paper();
    b["performed_at"] = json!("1970-01-01T00:00:00Z");
    assert_eq!(pointers(&b), Vec::<String>::new());
    b["performed_at"] = json!("1969-12-31T23:59:59Z");
    assert_eq!(pointers(&b), ["/performed_at"]);
}

/// The core's refusal of a run's reading count points at that run's
/// readings. (The checks before the core refuse such a run first; the
/// mapping stands behind them.)
#[test]
fn a_reading_count_refused_by_the_core_names_the_runs_readings() {
    let draft = read(Media::Json, &serde_json::to_vec(&paper()).unwrap()).unwrap();
    let (_, hints) = check(draft, now()).unwrap();
    let e = accelcal_core::Error::ReadingCount {
        run: 4,
        expected: 4,
        found: 3,
    };
    assert_eq!(hints.pointer_of(&e), "/runs/4/readings");
}

/// Where the core's other refusals point: a design that cannot separate the
/// terms at the model when one was given, else at the positions; no
/// positions at the positions; a non-finite sample at that sample.
#[test]
fn the_cores_refusals_name_the_model_positions_or_sample() {
    let rank = accelcal_core::Error::RankDeficient {
        terms: vec![Term::K0, Term::Ki],
        positions: 4,
        columns: 3,
        rank: 2,
    };
    let hints_of = |b: &Value| {
        let draft = read(Media::Json, &serde_json::to_vec(b).unwrap()).unwrap();
        check(draft, now()).unwrap().1
    };
    let given = hints_of(&paper());
    assert_eq!(given.pointer_of(&rank), "/model");
    let mut b = paper();
    b.as_object_mut().unwrap().remove("model");
    let default = hints_of(&b);
    assert_eq!(default.pointer_of(&rank), "/positions");
    assert_eq!(
        default.pointer_of(&accelcal_core::Error::NoPositions),
        "/positions"
    );
    let sample = accelcal_core::Error::NonFiniteSample {
        run: 1,
        position: 2,
        sample: 3,
    };
    assert_eq!(default.pointer_of(&sample), "/runs/1/readings/2/3");
    let gravity = accelcal_core::Error::NonFiniteGravity {
        position: 2,
        axis: 1,
    };
    assert_eq!(default.pointer_of(&gravity), "/positions/2");
}

/// Gravity components given with an angle may differ from the angle's by
/// up to 1e-3 g on each axis, not more.
#[test]
fn components_may_differ_from_the_angle_by_up_to_a_milli_g() {
    let mut b = paper();
    b["positions"][0] = json!({"angle_deg": 0, "a": [0.001, 1, 0]});
    assert_eq!(pointers(&b), Vec::<String>::new());
    b["positions"][0] = json!({"angle_deg": 0, "a": [0.0011, 1, 0]});
    assert_eq!(pointers(&b), ["/positions/0/a"]);
}

/// Issue 31: a refused model explains why its terms cannot be separated in
/// this mount and says how many to drop.
#[test]
fn model_refusals_say_why_and_how_many_terms_to_drop() {
    let detail = |model: Value| {
        let mut b = paper();
        b["model"] = model;
        match run(&b) {
            Err(Refused::Invalid(i)) => i.errors[0].detail.clone(),
            other => panic!("{other:?}"),
        }
    };
    let one = detail(json!(["k0", "ki", "kp", "ko"]));
    assert!(one.contains("a_o = 0 at every position"), "{one}");
    assert!(one.contains("pendulum mount"), "{one}");
    assert!(
        one.contains("drop ko from the model (it has 1 term more"),
        "{one}"
    );
    let two = detail(json!(["k0", "ki", "kp", "ko", "kio"]));
    assert!(
        two.contains("drop ko and kio from the model (it has 2 terms more"),
        "{two}"
    );
}

/// Issue 31: near-miss term names and kelvin-looking temperatures get a hint.
#[test]
fn near_misses_get_a_hint() {
    let mut b = paper();
    b["model"] = json!(["K0", "ki", "kp"]);
    let Err(Refused::Invalid(i)) = run(&b) else {
        panic!()
    };
    assert!(
        i.errors[0].detail.contains("did you mean `k0`?"),
        "{:?}",
        i.errors
    );
    let mut b = paper();
    for r in b["runs"].as_array_mut().unwrap() {
        r["temperature_c"] = json!(296.15);
    }
    let Err(Refused::Invalid(i)) = run(&b) else {
        panic!()
    };
    assert!(
        i.errors[0]
            .detail
            .ends_with("296.15 looks like kelvin: send degrees Celsius (23.00 °C)"),
        "{:?}",
        i.errors
    );
}

/// The radians body: refused at `/positions`, saying what to send.
/// A real tumble, even a fine one stepping by 5° over a quarter turn, passes.
#[test]
fn angles_in_radians_are_refused_with_the_degrees_to_send() {
    let mut b = paper();
    // The values, as a station sends them.
    let sent: Value = serde_json::from_str("[0, 1.5708, 3.1416, 4.7124]").unwrap();
    for (k, rad) in sent.as_array().unwrap().iter().enumerate() {
        b["positions"][k] = json!({"angle_deg": rad});
    }
    match run(&b) {
        Err(Refused::Invalid(i)) => {
            assert_eq!(i.errors.len(), 1);
            assert_eq!(i.errors[0].pointer, "/positions");
            let m = &i.errors[0].detail;
            assert!(m.contains("looks like radians"), "{m}");
            assert!(m.contains("(0, 90.00021, 180.000421, 270.000631)"), "{m}");
        }
        other => panic!("{other:?}"),
    }
    // The bound is 2π: an angle of 6.3 (beyond it) makes it degrees.
    b["positions"][3] = json!({"angle_deg": 6.3});
    assert!(
        !pointers(&b).contains(&"/positions".to_owned()),
        "{:?}",
        pointers(&b)
    );
    // One distinct angle is no tumble to judge.
    assert!(check::radians(&[]).is_none());
}

/// Naming standards needs the stand, and the stand's uncertainties may not
/// also be given in the body; the names are kept for the registry.
#[test]
fn standards_name_the_stand_and_replace_the_bodys_stand() {
    let mut named = paper();
    named["standards"] = json!({"stand": "STAND-1", "thermometer": "T-7"});
    let e = run(&named).unwrap();
    assert_eq!(
        e.submission.standards,
        Some(StandardsIn {
            stand: "STAND-1".into(),
            thermometer: Some("T-7".into()),
            gravity: None,
        })
    );
    assert!(e.submission.standards_used.is_empty(), "resolved later");
    let mut both = named.clone();
    both["stand"] = json!({"angle_std_arcsec": 1});
    assert_eq!(pointers(&both), ["/stand"]);
    let mut no_stand = paper();
    no_stand["standards"] = json!({"gravity": "G-BENCH"});
    assert_eq!(pointers(&no_stand), ["/standards/stand"]);
}

/// The item's receipt: kept when given, refused after the test was
/// performed or ahead of the clock; read from CSV metadata alike.
#[test]
fn the_items_receipt_precedes_its_calibration() {
    let mut body = paper();
    body["performed_at"] = json!("2026-06-02T08:00:00Z");
    body["item_received_at"] = json!("2026-06-01T09:30:00Z");
    body["item_condition"] = json!("no visible damage; connector cap missing");
    let s = run(&body).unwrap().submission;
    assert_eq!(
        s.item_received_at,
        Some(Timestamp::parse("2026-06-01T09:30:00Z").unwrap())
    );
    assert_eq!(
        s.item_condition.as_deref(),
        Some("no visible damage; connector cap missing")
    );
    let mut late = body.clone();
    late["item_received_at"] = json!("2026-06-03T00:00:00Z");
    assert_eq!(pointers(&late), ["/item_received_at"]);
    let mut ahead = paper();
    ahead["item_received_at"] = json!("2099-01-01T00:00:00Z");
    assert_eq!(pointers(&ahead), ["/item_received_at"]);
    let mut two_lines = body.clone();
    two_lines["item_condition"] = json!("dented\ncase");
    assert_eq!(pointers(&two_lines), ["/item_condition"]);
    let csv = format!(
        "# sensor_id: S-1\n# performed_at: 2026-06-02T08:00:00Z\n# item_received_at: 2026-06-01T09:30:00Z\n# item_condition: sealed\n{}",
        include_str!("../../../core/tests/data/table1.csv")
    );
    let s = evaluate(Media::Csv, csv.as_bytes(), now())
        .unwrap()
        .submission;
    assert_eq!(s.item_condition.as_deref(), Some("sealed"));
    assert!(s.item_received_at.is_some());
}
