//! Unit tests of the CSV layout.

use super::*;
use crate::domain::limits::MAX_LISTED_ERRORS;
use accelcal_core::Reading;

fn errors(text: &str) -> Vec<String> {
    let d = read(text.as_bytes()).unwrap();
    d.errors
        .into_invalid()
        .errors
        .into_iter()
        .map(|e| e.detail)
        .collect()
}

fn paper(prefix: &str) -> String {
    format!(
        "{prefix}{}",
        include_str!("../../../../core/tests/data/table1.csv")
    )
}

#[test]
fn paper_table_reads_like_the_json_example() {
    let d = read(
        paper("# sensor_id: PAPER-2005\n# unit: mA\n# model: k0, ki, kp\n# batches: 2\n")
            .as_bytes(),
    )
    .unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    assert_eq!(d.sensor_id, Slot::Value("PAPER-2005".into()));
    assert_eq!(d.unit, Slot::Value("mA".into()));
    assert_eq!(d.model, Slot::Value(vec![Term::K0, Term::Ki, Term::Kp]));
    assert_eq!(d.batches, Slot::Value(2));
    let Slot::Value(positions) = &d.positions else {
        panic!()
    };
    assert_eq!(positions.len(), 4);
    assert_eq!(positions[1].as_ref().unwrap().angle_deg, Some(90.0));
    let Slot::Value(runs) = &d.runs else { panic!() };
    assert_eq!(runs.len(), 6);
    assert_eq!(
        runs[0].as_ref().unwrap().readings[0],
        Reading::Samples(vec![0.005341914, 0.005679272])
    );
}

#[test]
fn quoted_commas_quotes_and_newlines_round_trip() {
    let text = "run,angle_deg,label,output\r\n1,0,\"up, \"\"north\"\"\nside\",1.5\r\n";
    let d = read(text.as_bytes()).unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    let Slot::Value(p) = &d.positions else {
        panic!()
    };
    assert_eq!(
        p[0].as_ref().unwrap().label.as_deref(),
        Some("up, \"north\"\nside")
    );
}

#[test]
fn after_the_header_every_line_is_data() {
    // A label and a run starting with `#` are values, not comments.
    let text = "run,angle_deg,label,output\n#1,0,#1 PA up,1\n#1,90,x,2\n";
    let d = read(text.as_bytes()).unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    let Slot::Value(p) = &d.positions else {
        panic!()
    };
    assert_eq!(p[0].as_ref().unwrap().label.as_deref(), Some("#1 PA up"));
    let Slot::Value(r) = &d.runs else { panic!() };
    assert_eq!(r.len(), 1);
}

#[test]
fn spreadsheet_exports_are_accepted() {
    let bom = "\u{feff}# sensor_id: X\rrun,angle_deg,output\r1,0,1\r1,90,2\r";
    let d = read(bom.as_bytes()).unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    assert_eq!(d.sensor_id, Slot::Value("X".into()));
    let Slot::Value(p) = &d.positions else {
        panic!()
    };
    assert_eq!(p.len(), 2);
}

#[test]
fn errors_name_lines_and_fields() {
    let e = errors("run,angle,output\n");
    assert!(
        e[0].starts_with("CSV line 1: unknown column `angle`"),
        "{e:?}"
    );
    let e = errors("run,angle_deg,output\n1,0,1.0\n1,90,NaN\n1,180\n");
    assert_eq!(e.len(), 2, "{e:?}");
    assert!(e[0].starts_with("CSV line 3"), "{e:?}");
    assert!(e[1].starts_with("CSV line 4"), "{e:?}");
    let e = errors("run,angle_deg,output\n1,0,1\n1,90,2\n2,0,1\n");
    assert_eq!(
        e,
        ["CSV: run `2` has no samples at position 1 (angle_deg 90)"],
        "the empty cell's position is described"
    );
    // A metadata line at fault is the problem; the missing header after it
    // is not reported again.
    let e = errors("# sensor: x\n");
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(e[0].contains("unknown field `sensor`"), "{e:?}");
    let e = errors("# Station ID: x\nrun,angle_deg,output\n1,0,1\n");
    assert!(
        e[0].contains("CSV line 1: unknown field `Station ID`"),
        "{e:?}"
    );
    assert_eq!(errors(""), ["CSV line 1: no header line and no samples"]);
    assert_eq!(
        errors("# sensor_id: S-1\n"),
        ["CSV line 2: no header line and no samples"]
    );
    let d =
        read(b"# batches: many\n# notes just a comment\nrun,angle_deg,output\n1,0,1\n").unwrap();
    let inv = d.errors.into_invalid();
    assert_eq!(inv.errors.len(), 1, "{inv:?}");
    assert_eq!(inv.errors[0].pointer, "/batches");
}

#[test]
fn limits_are_checked_while_reading() {
    // Every row a new run and a new angle: stops at the position limit
    // after reading no more than it, with one error.
    let mut text = String::from("run,angle_deg,output\n");
    for k in 0..5000 {
        text += &format!("r{k},{}.5,1\n", k % 3000);
    }
    let e = errors(&text);
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(e[0].contains("beyond the 360 accepted"), "{e:?}");
    // Many runs, few positions, cells missing: the list is capped.
    let mut text = String::from("run,angle_deg,output\n");
    for k in 0..300 {
        text += &format!("r{k},{},1\n", k % 300);
    }
    let d = read(text.as_bytes()).unwrap();
    let inv = d.errors.into_invalid();
    assert_eq!(inv.errors.len(), MAX_LISTED_ERRORS);
    assert!(inv.omitted > 80_000, "{}", inv.omitted);
}

#[test]
fn standards_come_from_metadata() {
    let text = "# standard_stand: STAND-1\n# standard_thermometer: T-7\n\
                run,angle_deg,output\n1,0,1\n1,90,2\n";
    let d = read(text.as_bytes()).unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    let Slot::Value(s) = &d.standards else {
        panic!()
    };
    assert_eq!(
        (
            s.stand.as_deref(),
            s.thermometer.as_deref(),
            s.gravity.as_deref()
        ),
        (Some("STAND-1"), Some("T-7"), None)
    );
    let d = read(b"# standard_gravity: not an id\nrun,angle_deg,output\n1,0,1\n").unwrap();
    let at: Vec<String> = d
        .errors
        .into_invalid()
        .errors
        .into_iter()
        .map(|e| e.pointer)
        .collect();
    assert!(at.iter().any(|p| p == "/standard_gravity"), "{at:?}");
}

#[test]
fn temperatures_and_the_stand_come_from_columns_and_metadata() {
    let text = "# sensor_type: NAV\n# stand_id: DH-1\n# stand_angle_std_arcsec: 3.5\n# stand_gravity_rel_std: 1e-5\n\
                run,angle_deg,temperature_c,output\n1,0,20,1\n1,90,20,2\n2,0,30,1.1\n2,90,30,2.1\n";
    let d = read(text.as_bytes()).unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    assert_eq!(d.sensor_type, Slot::Value("NAV".into()));
    let Slot::Value(stand) = &d.stand else {
        panic!()
    };
    assert_eq!(
        (
            stand.id.as_deref(),
            stand.angle_std_arcsec,
            stand.gravity_rel_std
        ),
        (Some("DH-1"), Some(3.5), Some(1e-5))
    );
    let Slot::Value(runs) = &d.runs else { panic!() };
    let temps: Vec<Option<f64>> = runs
        .iter()
        .map(|r| r.as_ref().unwrap().temperature_c)
        .collect();
    assert_eq!(temps, [Some(20.0), Some(30.0)]);
    // One per position (a chamber that drifts): the run's is their mean.
    let d = read(b"run,angle_deg,temperature_c,output\n1,0,20,1\n1,0,20,1.1\n1,90,21,2\n").unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    let Slot::Value(runs) = &d.runs else { panic!() };
    let run = runs[0].as_ref().unwrap();
    assert_eq!(
        (run.temperature_c, &run.position_temperatures_c),
        (Some(20.5), &Some(vec![20.0, 21.0]))
    );
    // Not within one position, nor at some positions only.
    let e = errors("run,angle_deg,temperature_c,output\n1,0,20,1\n1,0,21,1.1\n1,90,21,2\n");
    assert!(
        e[0].contains("CSV line 3: `temperature_c` differs within run `1` at one position"),
        "{e:?}"
    );
    let e = errors("run,angle_deg,temperature_c,output\n1,0,20,1\n1,90,,2\n");
    assert!(
        e[0].contains("at some positions and not at others"),
        "{e:?}"
    );
    let e = errors("run,angle_deg,temperature_c,output\n1,0,900,1\n");
    assert!(
        e[0].contains("`temperature_c` must be a temperature"),
        "{e:?}"
    );
    let d = read(b"# stand_angle_std_arcsec: lots\nrun,angle_deg,output\n1,0,1\n").unwrap();
    assert_eq!(
        d.errors.into_invalid().errors[0].pointer,
        "/stand_angle_std_arcsec"
    );
}

#[test]
fn the_station_comes_from_its_metadata_line() {
    let d = read(b"# station_id: ST-4\nrun,angle_deg,output\n1,0,1\n").unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    assert_eq!(d.station_id, Slot::Value("ST-4".into()));
    let d = read(b"# station_id: two words\nrun,angle_deg,output\n1,0,1\n").unwrap();
    assert_eq!(d.station_id, Slot::Invalid);
    assert_eq!(d.errors.into_invalid().errors[0].pointer, "/station_id");
}

/// A model may name every term there is, once each; one name more is
/// refused with the count allowed.
#[test]
fn a_model_may_name_every_term() {
    let all: Vec<&str> = Term::ALL.iter().map(|t| t.name()).collect();
    let d = read(format!("# model: {}\nrun,angle_deg,output\n1,0,1\n", all.join(", ")).as_bytes())
        .unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    assert_eq!(d.model, Slot::Value(Term::ALL.to_vec()));
    let e = errors(&format!(
        "# model: {}, k0\nrun,angle_deg,output\n1,0,1\n",
        all.join(", ")
    ));
    assert_eq!(
        e,
        [format!("must name 1 to {} terms", Term::ALL.len())],
        "{e:?}"
    );
}

/// Positions may be given by their gravity components alone (no angle),
/// and blank lines between rows — empty or spaces only — are skipped.
#[test]
fn gravity_columns_stand_for_the_angle_and_blank_lines_are_skipped() {
    let d = read(b"run,a_i,a_p,a_o,output\n1,1,0,0,1.5\n\n   \n1,-1,0,0,-0.5\n").unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    let Slot::Value(runs) = &d.runs else { panic!() };
    assert_eq!(
        runs[0].as_ref().unwrap().readings,
        [Reading::from(vec![1.5]), Reading::from(vec![-0.5])]
    );
}

/// One cell (a run at a position) holds at most MAX_SAMPLES samples: that
/// many pass, one more is named at its line.
#[test]
fn a_cell_may_hold_the_sample_limit_but_not_pass_it() {
    let cell = |n: usize| {
        let mut text = String::from("run,angle_deg,output\n");
        for _ in 0..n {
            text += "1,0,1.5\n";
        }
        text
    };
    assert_eq!(errors(&cell(MAX_SAMPLES)), Vec::<String>::new());
    let e = errors(&cell(MAX_SAMPLES + 1));
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(
        e[0].starts_with(&format!("CSV line {}:", MAX_SAMPLES + 2)),
        "{e:?}"
    );
}

/// Windows line ends count one line each (only CR-only files have their CRs
/// turned into line ends), blank lines among the metadata are skipped, and
/// `# mount:` is read like the JSON member.
#[test]
fn crlf_lines_count_once_blank_metadata_lines_are_skipped_and_mount_is_read() {
    let e = errors("run,angle_deg,output\r\n1,0,1.0\r\n1,90,NaN\r\n");
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(e[0].starts_with("CSV line 3:"), "{e:?}");
    let d =
        read(b"\n# sensor_id: X\n\n# mount: gate\nrun,angle_deg,output\n1,0,1\n1,90,2\n").unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    assert_eq!(d.sensor_id, Slot::Value("X".into()));
    assert_eq!(d.mount, Slot::Value(accelcal_core::Mount::Gate));
    let Slot::Value(p) = &d.positions else {
        panic!()
    };
    assert_eq!(p.len(), 2);
    let e = errors("# mount: sideways\nrun,angle_deg,output\n1,0,1\n");
    assert_eq!(e, ["must be \"pendulum\" or \"gate\""], "{e:?}");
}

#[test]
fn notes_are_read_and_checked_like_the_json_member() {
    let d = read(b"# notes: after the stand's service\nrun,angle_deg,output\n1,0,1\n").unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    assert_eq!(d.notes, Slot::Value("after the stand's service".into()));
    let long = format!(
        "# notes: {}\nrun,angle_deg,output\n1,0,1\n",
        "n".repeat(MAX_NOTES_CHARS + 1)
    );
    let d = read(long.as_bytes()).unwrap();
    assert_eq!(d.notes, Slot::Invalid);
    let e = d.errors.into_invalid().errors;
    assert_eq!(e.len(), 1, "{e:?}");
    assert_eq!(e[0].pointer, "/notes", "{e:?}");
}

/// Issue 31: a bad cell is one error naming its line, column and value —
/// not also "positions/runs are required" — with a hint for a unit typed
/// into the cell.
#[test]
fn a_bad_cell_is_one_error_with_its_line_column_and_value() {
    let text = paper("# sensor_id: C-1\n").replacen(",0.005341914", ",0.005341914 mA", 1);
    let e = errors(&text);
    assert_eq!(
        e,
        [
            "CSV line 3: column 7 (`output`): `0.005341914 mA` is not a number \
          (a number alone: the unit goes in a `# unit: …` line)"
        ]
    );
    let text = paper("").replacen("\n1,90,", "\n1,ninety,", 1);
    let e = errors(&text);
    assert_eq!(
        e,
        ["CSV line 4: column 2 (`angle_deg`): `ninety` is not a number"]
    );
    let d = read(text.as_bytes()).unwrap();
    assert_eq!(d.positions, Slot::Invalid);
    assert_eq!(d.runs, Slot::Invalid);
}

/// Issue 31: a file separated by `;` or tabs is told to use commas.
#[test]
fn semicolons_and_tabs_are_told_to_be_commas() {
    for (sep, name) in [(";", "`;`"), ("\t", "tabs")] {
        let e = errors(&paper("").replace(',', sep));
        assert_eq!(e.len(), 1, "{e:?}");
        assert!(
            e[0].starts_with("CSV line 1: the header is one column separated by "),
            "{e:?}"
        );
        assert!(e[0].contains(name) && e[0].contains("commas"), "{e:?}");
    }
}

/// Issue 31: an angle that matches no other run's (89 for 90 in run 4)
/// blames its own line and names the position it probably meant, instead
/// of every other run for lacking it.
#[test]
fn a_mistyped_angle_blames_its_own_line() {
    let text = paper("").replace("\n4,90,", "\n4,89,");
    let e = errors(&text);
    let line = text
        .lines()
        .position(|l| l.starts_with("4,89,"))
        .map(|i| i + 1)
        .unwrap();
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(
        e[0].starts_with(&format!("CSV line {line}: position (angle_deg 89")),
        "{e:?}"
    );
    assert!(
        e[0].contains("run `4` only") && e[0].contains("90°"),
        "{e:?}"
    );
}

/// A station that averages on board sends `mean`, `std` and `count`
/// columns: one row per run and position.
#[test]
fn summary_columns_give_one_reading_per_row() {
    let d = read(b"run,angle_deg,mean,std,count\n1,0,1.5,0.1,10\n1,180,-0.5,0,1\n").unwrap();
    assert!(d.errors.is_empty(), "{:?}", d.errors);
    let Slot::Value(runs) = &d.runs else { panic!() };
    let summary = |mean, std, count| Reading::Summary(accelcal_core::Summary { mean, std, count });
    assert_eq!(
        runs[0].as_ref().unwrap().readings,
        [summary(1.5, 0.1, 10), summary(-0.5, 0.0, 1)]
    );
    assert_eq!(
        errors("run,angle_deg,output,mean,std,count\n1,0,1,1,0,1\n"),
        [
            "CSV line 1: give an `output` column (one sample per row) or `mean`, `std`, `count` \
             columns (one summary per row), not both"
        ]
    );
    assert_eq!(
        errors("run,angle_deg,mean,std\n1,0,1,0\n"),
        ["CSV line 1: give all of `mean`, `std`, `count` or none"]
    );
    assert_eq!(
        errors("run,angle_deg,mean,std,count\n1,0,1,0,2\n1,0,1,0,2\n"),
        [
            "CSV line 3: a second summary of run `1` at one position; a summary row stands for \
             all of a position's samples"
        ]
    );
    assert_eq!(
        errors("run,angle_deg,mean,std,count\n1,0,1,0.1,1\n1,90,1,-1,2\n1,180,1,0,0\n"),
        [
            "CSV line 2: column 4 (`std`): must be 0 when `count` is 1: one sample has no spread"
                .to_owned(),
            "CSV line 3: column 4 (`std`): must not be negative".to_owned(),
            format!(
                "CSV line 4: column 5 (`count`): `0` is not an integer from 1 to {MAX_SUMMARY_COUNT}"
            ),
        ]
    );
}
