//! Unit tests of the JSON reader.

use super::*;
use accelcal_core::Reading;

fn pointers(body: &str) -> Vec<String> {
    let d = read(body.as_bytes()).unwrap();
    d.errors
        .into_invalid()
        .errors
        .into_iter()
        .map(|e| e.pointer)
        .collect()
}

#[test]
fn reads_every_field() {
    let d = read(include_bytes!("../../../../examples/paper-table1.json")).unwrap();
    assert!(d.errors.is_empty());
    assert_eq!(d.sensor_id, Slot::Value("PAPER-2005".into()));
    let Slot::Value(runs) = &d.runs else { panic!() };
    assert_eq!(runs.len(), 6);
    assert_eq!(
        runs[0].as_ref().unwrap().readings[0],
        Reading::Samples(vec![0.005341914, 0.005679272])
    );
}

#[test]
fn kinds_counts_and_duplicates_are_reported_in_document_order() {
    assert_eq!(pointers("[]"), [""]);
    assert_eq!(
        pointers(
            r#"{"sensor_id": 5, "x": {"deep": [[[]]]}, "sensor_id": "a", "runs": [{"readings": [[1, "2", null]]}, 7]}"#
        ),
        [
            "/sensor_id",
            "/x",
            "/sensor_id",
            "/runs/0/readings/0/1",
            "/runs/0/readings/0/2",
            "/runs/1"
        ]
    );
    assert_eq!(
        pointers(
            r#"{"positions": [{"angle_deg": 0, "angle_deg": 1}, {"a": [1, 0]}, {"a": [0, 0, 0]}]}"#
        ),
        ["/positions/0/angle_deg", "/positions/1/a", "/positions/2/a"]
    );
    assert_eq!(
        pointers(r#"{"model": ["k0", "K1", "k0"], "batches": 2.0}"#),
        ["/model/1", "/model/2", "/batches"]
    );
}

#[test]
fn counts_are_checked_while_reading_and_nothing_beyond_is_kept() {
    let samples = vec!["1"; MAX_SAMPLES + 5].join(",");
    let d = read(format!(r#"{{"runs": [{{"readings": [[{samples}]]}}]}}"#).as_bytes()).unwrap();
    let inv = d.errors.into_invalid();
    assert_eq!(inv.errors[0].pointer, "/runs/0/readings/0");
    assert!(
        inv.errors[0].detail.contains(&format!(
            "at most {MAX_SAMPLES} elements, not {}",
            MAX_SAMPLES + 5
        )),
        "{inv:?}"
    );
}

#[test]
fn syntax_errors_abort_with_the_parsers_message() {
    assert!(read(b"{\"sensor_id\": ").is_err());
    assert!(read(b"{} x").is_err());
    assert!(read(br#"{"runs": [{"readings": [[1e400]]}]}"#).is_err());
    let e = read(b"{\"a\": tru}").unwrap_err();
    assert!(e.contains("line 1 column"), "where it breaks is said: {e}");
}

/// Reads `body`, whose one problem is `detail` at `pointer`.
fn one_problem(body: &[u8], pointer: &str, detail: &str) -> Draft {
    let mut d = read(body).unwrap();
    let inv = std::mem::take(&mut d.errors).into_invalid();
    assert_eq!(inv.errors.len(), 1, "{inv:?}");
    assert_eq!(inv.errors[0].pointer, pointer);
    assert_eq!(inv.errors[0].detail, detail);
    d
}

/// Reads `body`, which has no problem.
fn no_problem(body: &[u8]) -> Draft {
    let d = read(body).unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    d
}

#[test]
fn the_stand_is_an_object_or_absent() {
    assert_eq!(no_problem(br#"{"stand": null}"#).stand, Slot::Absent);
    let d = one_problem(
        br#"{"stand": 5}"#,
        "/stand",
        "must be an object, not a number",
    );
    assert_eq!(d.stand, Slot::Invalid);
}

#[test]
fn the_model_is_an_array_or_absent() {
    assert_eq!(no_problem(br#"{"model": null}"#).model, Slot::Absent);
    let d = one_problem(
        br#"{"model": "k0"}"#,
        "/model",
        "must be an array, not a string",
    );
    assert_eq!(d.model, Slot::Invalid);
}

/// The stand's uncertainties run from 0 (inclusive) to their bounds: a
/// negative one is named.
#[test]
fn the_stands_uncertainties_are_not_negative() {
    no_problem(br#"{"stand": {"angle_std_arcsec": 0, "gravity_rel_std": 0}}"#);
    assert_eq!(
        pointers(r#"{"stand": {"angle_std_arcsec": -1e-9, "gravity_rel_std": -1}}"#),
        ["/stand/angle_std_arcsec", "/stand/gravity_rel_std"]
    );
    // One bad member makes the whole stand invalid, even after good ones:
    // nothing of it is used.
    let d = one_problem(
        br#"{"stand": {"id": "DH-1", "angle_std_arcsec": -1}}"#,
        "/stand/angle_std_arcsec",
        "must be a number from 0 to 3600",
    );
    assert_eq!(d.stand, Slot::Invalid);
}

/// `standards` names standards by id in three roles; anything else in it,
/// or an id that is not one, is named.
#[test]
fn standards_are_named_by_id_in_their_roles() {
    let d = read(br#"{"standards": {"stand": "STAND-1", "gravity": "G-BENCH"}}"#).unwrap();
    assert!(d.errors.is_empty());
    assert_eq!(
        d.standards,
        Slot::Value(StandardsDraft {
            stand: Some("STAND-1".into()),
            thermometer: None,
            gravity: Some("G-BENCH".into()),
        })
    );
    assert_eq!(
        pointers(r#"{"standards": {"stand": "has space", "thermometer": 5}}"#),
        ["/standards/stand", "/standards/thermometer"]
    );
    assert_eq!(
        pointers(r#"{"standards": {"stand": "S", "oven": "X"}}"#),
        ["/standards/oven"]
    );
    assert_eq!(pointers(r#"{"standards": "STAND-1"}"#), ["/standards"]);
    assert_eq!(
        read(br#"{"standards": null}"#).unwrap().standards,
        Slot::Absent
    );
}

#[test]
fn the_runs_are_an_array_or_absent() {
    assert_eq!(no_problem(br#"{"runs": null}"#).runs, Slot::Absent);
    let d = one_problem(br#"{"runs": 6}"#, "/runs", "must be an array, not a number");
    assert_eq!(d.runs, Slot::Invalid);
}

#[test]
fn the_positions_are_an_array_or_absent() {
    assert_eq!(
        no_problem(br#"{"positions": null}"#).positions,
        Slot::Absent
    );
    let d = one_problem(
        br#"{"positions": 4}"#,
        "/positions",
        "must be an array, not a number",
    );
    assert_eq!(d.positions, Slot::Invalid);
    one_problem(
        br#"{"positions": [{"angle_deg": 0}, 90]}"#,
        "/positions/1",
        "must be an object, not a number",
    );
}

/// A position's `a` is an array of three components, or `null` (absent: the
/// angle alone gives the position).
#[test]
fn gravity_components_are_an_array_or_absent() {
    let d = no_problem(br#"{"positions": [{"angle_deg": 90, "a": null}]}"#);
    let Slot::Value(p) = d.positions else {
        panic!("{:?}", d.positions)
    };
    assert_eq!(p[0].as_ref().unwrap().angle_deg, Some(90.0));
    one_problem(
        br#"{"positions": [{"angle_deg": 90, "a": "down"}]}"#,
        "/positions/0/a",
        "must be an array, not a string",
    );
    // A wrong component is named alone: the other two are not judged as a
    // vector of two.
    let inv = read(br#"{"positions": [{"a": [0, "x", 1]}]}"#)
        .unwrap()
        .errors
        .into_invalid();
    assert_eq!(inv.errors.len(), 1, "{inv:?}");
    assert_eq!(inv.errors[0].pointer, "/positions/0/a/1");
}

/// An empty array is said to be empty; a short one, how short.
#[test]
fn arrays_too_short_say_how_short() {
    one_problem(br#"{"runs": []}"#, "/runs", "must not be empty");
    one_problem(
        br#"{"positions": [{"a": [1, 0]}]}"#,
        "/positions/0/a",
        "must hold at least 3 elements, not 2",
    );
    one_problem(
        br#"{"positions": [{"a": []}]}"#,
        "/positions/0/a",
        "must not be empty",
    );
}

/// A run with any wrong member is left out whole, so that no later check
/// judges what is left of it; its problems are said once.
#[test]
fn a_run_with_a_wrong_member_is_left_out_whole() {
    for (body, pointer) in [
        (
            &br#"{"runs": [{"readings": [[1]], "speed": 3}, {"readings": [[1]]}]}"#[..],
            "/runs/0/speed",
        ),
        (
            br#"{"runs": [{"readings": [[1]], "temperature_c": "warm"}, {"readings": [[1]]}]}"#,
            "/runs/0/temperature_c",
        ),
        (
            br#"{"runs": [{"readings": [[1]], "readings": [[2]]}, {"readings": [[1]]}]}"#,
            "/runs/0/readings",
        ),
    ] {
        let mut d = read(body).unwrap();
        let inv = std::mem::take(&mut d.errors).into_invalid();
        assert_eq!(inv.errors.len(), 1, "{inv:?}");
        assert_eq!(inv.errors[0].pointer, pointer);
        let Slot::Value(runs) = d.runs else {
            panic!("{:?}", d.runs)
        };
        assert!(runs[0].is_none(), "{:?}", runs[0]);
        assert_eq!(
            runs[1].as_ref().unwrap().readings,
            [Reading::from(vec![1.0])]
        );
    }
}

/// A position's reading may be its samples or their summary, side by side
/// in one run; a summary's problems name its members.
#[test]
fn a_reading_is_samples_or_a_summary() {
    let d = no_problem(
        br#"{"runs": [{"readings": [{"count": 10, "mean": 1.5, "std": 0.1}, [1, 2]]}]}"#,
    );
    let Slot::Value(runs) = &d.runs else { panic!() };
    assert_eq!(
        runs[0].as_ref().unwrap().readings,
        [
            Reading::Summary(accelcal_core::Summary {
                mean: 1.5,
                std: 0.1,
                count: 10
            }),
            Reading::from(vec![1.0, 2.0])
        ]
    );
    let at = |k: &str| format!("/runs/0/readings/0/{k}");
    assert_eq!(
        pointers(r#"{"runs": [{"readings": [{"mean": "a", "std": -1, "count": 0}]}]}"#),
        [at("mean"), at("std"), at("count")]
    );
    one_problem(
        br#"{"runs": [{"readings": [{"mean": 1, "std": 0.5, "count": 1}]}]}"#,
        &at("std"),
        "must be 0 when `count` is 1: one sample has no spread",
    );
    one_problem(
        br#"{"runs": [{"readings": [{"mean": 1, "std": 0, "count": 2, "n": 2}]}]}"#,
        &at("n"),
        "unknown field `n`; expected one of: mean, std, count",
    );
    one_problem(
        br#"{"runs": [{"readings": [{"mean": 1, "std": 0, "count": 2.5}]}]}"#,
        &at("count"),
        &format!("must be an integer from 1 to {MAX_SUMMARY_COUNT}"),
    );
    one_problem(
        br#"{"runs": [{"readings": [{"mean": 1, "count": 2}]}]}"#,
        &at("std"),
        "is required",
    );
    one_problem(
        br#"{"runs": [{"readings": [7]}]}"#,
        "/runs/0/readings/0",
        "must be an array of samples or an object of `mean`, `std` and `count`, not a number",
    );
}

/// Summarised samples were never sent: they do not count against the
/// limit on samples in all.
#[test]
fn summarised_samples_are_not_counted_against_the_limits() {
    let summary = format!(r#"{{"mean": 1, "std": 0.1, "count": {MAX_SUMMARY_COUNT}}}"#);
    let readings = [summary.as_str(); 4].join(",");
    let d = no_problem(format!(r#"{{"runs": [{{"readings": [{readings}]}}]}}"#).as_bytes());
    let Slot::Value(runs) = &d.runs else { panic!() };
    assert_eq!(
        runs[0].as_ref().unwrap().readings[3].count(),
        MAX_SUMMARY_COUNT
    );
}

#[test]
fn a_run_gives_its_temperature_or_one_per_position() {
    let d = no_problem(
        br#"{"runs": [{"readings": [[1], [2], [3], [4]], "temperature_c": [20, 20.5, 21, 21.5]},
                      {"readings": [[1], [2], [3], [4]], "temperature_c": 30}]}"#,
    );
    let Slot::Value(runs) = d.runs else {
        panic!("{:?}", d.runs)
    };
    let drifting = runs[0].as_ref().unwrap();
    assert_eq!(drifting.temperature_c, Some(20.75), "their mean");
    assert_eq!(
        drifting.position_temperatures_c,
        Some(vec![20.0, 20.5, 21.0, 21.5])
    );
    let steady = runs[1].as_ref().unwrap();
    assert_eq!(
        (steady.temperature_c, &steady.position_temperatures_c),
        (Some(30.0), &None)
    );
    one_problem(
        br#"{"runs": [{"readings": [[1], [2]], "temperature_c": [20, 21, 22]}]}"#,
        "/runs/0/temperature_c",
        "must be the run's temperature or one per position (2), not 3",
    );
    let d =
        read(br#"{"runs": [{"readings": [[1], [2]], "temperature_c": [20, 294.15]}]}"#).unwrap();
    let inv = d.errors.into_invalid();
    assert_eq!(inv.errors.len(), 1, "{inv:?}");
    assert_eq!(inv.errors[0].pointer, "/runs/0/temperature_c/1");
    assert!(inv.errors[0].detail.contains("looks like kelvin"));
    one_problem(
        br#"{"runs": [{"readings": [[1]], "temperature_c": []}]}"#,
        "/runs/0/temperature_c",
        "must not be empty",
    );
}
