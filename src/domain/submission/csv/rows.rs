//! The header and rows after it: every line is one sample (or one run's
//! summary at a position), read with the `csv` crate; positions and runs are
//! indexed by hash as they first appear, and the limits are checked while
//! reading.

use std::collections::HashMap;
use std::collections::hash_map::Entry;

use accelcal_core::{Reading, Summary};

use super::super::draft::{Draft, PositionDraft, RunDraft, Slot};
use super::super::json::{gravity, temperature};
use super::super::node::Scalar;
use super::{COLUMNS, at_line};
use crate::domain::field::{Errors, Loc};
use crate::domain::limits::*;
use crate::domain::text::{Chars, check_str, echo};

/// Where a row's reading is: one sample's `output`, or a summary's `mean`,
/// `std` and `count`.
#[derive(Clone, Copy)]
enum Value {
    Output(usize),
    Summary([usize; 3]),
}

/// The header's column indices.
struct Header {
    run: usize,
    value: Value,
    angle: Option<usize>,
    components: Option<[usize; 3]>,
    label: Option<usize>,
    temperature: Option<usize>,
    len: usize,
}

fn header(cols: &[String], line: usize, errors: &mut Errors) -> Option<Header> {
    if let Some(hint) = separator_hint(cols) {
        at_line(errors, line, hint);
        return None;
    }
    let find = |c: &str| cols.iter().position(|x| x == c);
    let mut ok = true;
    let mut fail = |errors: &mut Errors, why: String| {
        at_line(errors, line, why);
        ok = false;
    };
    for (k, c) in cols.iter().enumerate() {
        if !COLUMNS.contains(&c.as_str()) {
            fail(
                errors,
                format!(
                    "unknown column `{}`; expected: {}",
                    echo(c),
                    COLUMNS.join(", ")
                ),
            );
        } else if cols[..k].contains(c) {
            fail(errors, format!("column `{c}` appears twice"));
        }
    }
    let summary = [find("mean"), find("std"), find("count")];
    let value = match (find("output"), summary) {
        (Some(k), [None, None, None]) => Some(Value::Output(k)),
        (None, [Some(m), Some(s), Some(n)]) => Some(Value::Summary([m, s, n])),
        (Some(_), _) => {
            fail(
                errors,
                "give an `output` column (one sample per row) or `mean`, `std`, `count` \
                 columns (one summary per row), not both"
                    .into(),
            );
            None
        }
        (None, [None, None, None]) => {
            fail(
                errors,
                "the header needs an `output` column (or `mean`, `std`, `count`)".into(),
            );
            None
        }
        (None, _) => {
            fail(errors, "give all of `mean`, `std`, `count` or none".into());
            None
        }
    };
    let run = find("run").or_else(|| find("test"));
    if run.is_none() {
        fail(errors, "the header needs a `run` column".into());
    }
    let explicit = [find("a_i"), find("a_p"), find("a_o")];
    let given = explicit.iter().flatten().count();
    if given != 0 && given != 3 {
        fail(errors, "give all of `a_i`, `a_p`, `a_o` or none".into());
    }
    let angle = find("angle_deg");
    if angle.is_none() && given == 0 {
        fail(
            errors,
            "the header needs `angle_deg` or `a_i`, `a_p`, `a_o` columns".into(),
        );
    }
    Some(Header {
        run: run?,
        value: value?,
        angle,
        components: match explicit {
            [Some(i), Some(p), Some(o)] => Some([i, p, o]),
            _ => None,
        },
        label: find("label"),
        temperature: find("temperature_c"),
        len: cols.len(),
    })
    .filter(|_| ok)
}

/// A finite number of magnitude at most `bound` from the cell in column
/// `k` (0-based) named `column`; the error names the column by position
/// and name and shows the value.
fn number(cell: &str, k: usize, column: &str, bound: f64) -> Result<f64, String> {
    match cell.parse::<f64>() {
        Ok(x) if x.is_finite() && x.abs() <= bound => Ok(x),
        Ok(_) => Err(format!(
            "column {} (`{column}`): `{}` is not a finite number of magnitude at most {bound:e}",
            k + 1,
            echo(cell)
        )),
        Err(_) => {
            let unit = cell
                .split_once(char::is_whitespace)
                .filter(|(n, _)| n.parse::<f64>().is_ok());
            let hint = if unit.is_some() {
                " (a number alone: the unit goes in a `# unit: …` line)"
            } else {
                ""
            };
            Err(format!(
                "column {} (`{column}`): `{}` is not a number{hint}",
                k + 1,
                echo(cell)
            ))
        }
    }
}

/// A hint when a header of one column looks separated by something else
/// than commas (`;` or a tab, as spreadsheets in many locales write).
fn separator_hint(cols: &[String]) -> Option<String> {
    let [only] = cols else { return None };
    [(';', "`;`"), ('\t', "tabs")]
        .into_iter()
        .find(|(c, _)| only.contains(*c))
        .map(|(_, name)| {
            format!(
                "the header is one column separated by {name}; separate the columns with commas \
                 (export the spreadsheet as CSV with `,` as the separator)"
            )
        })
}

/// One row as read: run, position and its sample or summary.
struct Sample {
    run: u32,
    position: u32,
    value: Cell,
}

/// A row's reading.
enum Cell {
    Sample(f64),
    Summary(Summary),
}

/// The summary in the `mean`, `std` and `count` columns `[m, s, n]`.
fn summary(record: &csv::StringRecord, [m, s, n]: [usize; 3]) -> Result<Summary, String> {
    let mean = number(&record[m], m, "mean", MAX_READING)?;
    let std = number(&record[s], s, "std", MAX_READING)?;
    if std < 0.0 {
        return Err(format!("column {} (`std`): must not be negative", s + 1));
    }
    let count = record[n]
        .parse::<u64>()
        .ok()
        .filter(|c| (1..=MAX_SUMMARY_COUNT).contains(c))
        .ok_or_else(|| {
            format!(
                "column {} (`count`): `{}` is not an integer from 1 to {MAX_SUMMARY_COUNT}",
                n + 1,
                echo(&record[n])
            )
        })?;
    if count == 1 && std != 0.0 {
        return Err(format!(
            "column {} (`std`): must be 0 when `count` is 1: one sample has no spread",
            s + 1
        ));
    }
    Ok(Summary { mean, std, count })
}

/// Reads the header and rows (from the header line on) into `draft`.
pub fn rows(text: &str, header_line: usize, draft: &mut Draft) {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let line_of =
        |r: &csv::StringRecord| header_line - 1 + r.position().map_or(1, |p| p.line() as usize);
    let mut records = reader.records();
    let head = match records.next() {
        Some(Ok(r)) => r,
        _ => {
            at_line(
                &mut draft.errors,
                header_line,
                "the header line cannot be read",
            );
            return;
        }
    };
    let cols: Vec<String> = head.iter().map(str::to_ascii_lowercase).collect();
    // Whatever goes wrong below has been said of its line: the positions
    // and runs the rows make up are not also "required".
    draft.positions = Slot::Invalid;
    draft.runs = Slot::Invalid;
    let Some(h) = header(&cols, header_line, &mut draft.errors) else {
        return;
    };

    let mut positions: Vec<PositionDraft> = Vec::new();
    // The line each position first appears on.
    let mut first_line: Vec<usize> = Vec::new();
    let mut position_index: HashMap<String, u32> = HashMap::new();
    let mut run_names: Vec<String> = Vec::new();
    // Each cell's (run × position) temperature, as its first row gave it.
    let mut cell_temperatures: HashMap<(u32, u32), Option<f64>> = HashMap::new();
    let mut run_index: HashMap<String, u32> = HashMap::new();
    let mut cell_counts: HashMap<(u32, u32), usize> = HashMap::new();
    let mut samples: Vec<Sample> = Vec::new();
    for record in records {
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                let line = e
                    .position()
                    .map_or(0, |p| header_line - 1 + p.line() as usize);
                at_line(&mut draft.errors, line, "the row cannot be read as CSV");
                continue;
            }
        };
        let line = line_of(&record);
        if record.len() == 1 && record[0].is_empty() {
            continue;
        }
        if record.len() != h.len {
            at_line(
                &mut draft.errors,
                line,
                format!("has {} fields, the header {}", record.len(), h.len),
            );
            continue;
        }
        let run = &record[h.run];
        if run.is_empty() {
            at_line(&mut draft.errors, line, "the run is empty");
            continue;
        }
        let value = match h.value {
            Value::Output(k) => number(&record[k], k, "output", MAX_READING).map(Cell::Sample),
            Value::Summary(cols) => summary(&record, cols).map(Cell::Summary),
        };
        let value = match value {
            Ok(x) => x,
            Err(why) => {
                at_line(&mut draft.errors, line, why);
                continue;
            }
        };
        let mut p = PositionDraft::default();
        let mut key = String::new();
        if let Some(k) = h.angle {
            match number(&record[k], k, "angle_deg", MAX_ANGLE_DEG) {
                Ok(deg) => {
                    key += &format!("{deg}|");
                    p.angle_deg = Some(deg);
                }
                Err(why) => {
                    at_line(&mut draft.errors, line, why);
                    continue;
                }
            }
        }
        if let Some(cols) = h.components {
            let a: Result<Vec<f64>, String> = cols
                .iter()
                .zip(["a_i", "a_p", "a_o"])
                .map(|(k, name)| number(&record[*k], *k, name, MAX_GRAVITY_COMPONENT))
                .collect();
            match a.and_then(|a| gravity([a[0], a[1], a[2]])) {
                Ok(g) => {
                    key += &format!("{:?}|", g.to_array());
                    p.a = Some(g);
                }
                Err(why) => {
                    at_line(&mut draft.errors, line, why);
                    continue;
                }
            }
        }
        if let Some(k) = h.label.filter(|k| !record[*k].is_empty()) {
            if let Err(why) = check_str(&record[k], MAX_LABEL_CHARS, Chars::Text) {
                at_line(&mut draft.errors, line, format!("`label` {why}"));
                continue;
            }
            key += &record[k];
            p.label = Some(record[k].to_owned());
        }
        let position = match position_index.entry(key) {
            Entry::Occupied(e) => *e.get(),
            Entry::Vacant(e) => {
                if positions.len() == MAX_POSITIONS {
                    at_line(
                        &mut draft.errors,
                        line,
                        format!("a position beyond the {MAX_POSITIONS} accepted"),
                    );
                    return;
                }
                positions.push(p);
                first_line.push(line);
                *e.insert(positions.len() as u32 - 1)
            }
        };
        let run = match run_index.get(run) {
            Some(r) => *r,
            None => {
                if run_names.len() == MAX_RUNS {
                    at_line(
                        &mut draft.errors,
                        line,
                        format!("a run beyond the {MAX_RUNS} accepted"),
                    );
                    return;
                }
                run_names.push(run.to_owned());
                run_index.insert(run.to_owned(), run_names.len() as u32 - 1);
                run_names.len() as u32 - 1
            }
        };
        if let Some(k) = h.temperature {
            let cell = &record[k];
            let t = if cell.is_empty() {
                None
            } else {
                match temperature(&Scalar::Num(cell.parse().unwrap_or(f64::NAN), None)) {
                    Ok(t) => Some(t),
                    Err(why) => {
                        at_line(&mut draft.errors, line, format!("`temperature_c` {why}"));
                        continue;
                    }
                }
            };
            // One temperature a position: a run's may differ between its
            // positions (a chamber that drifts), not within one.
            match cell_temperatures.entry((run, position)) {
                std::collections::hash_map::Entry::Occupied(e) if *e.get() != t => {
                    at_line(
                        &mut draft.errors,
                        line,
                        format!(
                            "`temperature_c` differs within run `{}` at one position: give the \
                             run's temperature, or one per position",
                            echo(&run_names[run as usize])
                        ),
                    );
                    continue;
                }
                std::collections::hash_map::Entry::Occupied(_) => {}
                std::collections::hash_map::Entry::Vacant(e) => {
                    e.insert(t);
                }
            }
        }
        let count = cell_counts.entry((run, position)).or_default();
        *count += 1;
        if matches!(value, Cell::Summary(_)) && *count > 1 {
            at_line(
                &mut draft.errors,
                line,
                format!(
                    "a second summary of run `{}` at one position; a summary row stands for \
                     all of a position's samples",
                    echo(&run_names[run as usize])
                ),
            );
            continue;
        }
        if *count > MAX_SAMPLES {
            at_line(
                &mut draft.errors,
                line,
                format!(
                    "more than {MAX_SAMPLES} samples of run `{}` at one position",
                    echo(&run_names[run as usize])
                ),
            );
            return;
        }
        if samples.len() == MAX_TOTAL_SAMPLES {
            at_line(
                &mut draft.errors,
                line,
                format!("more than {MAX_TOTAL_SAMPLES} samples in all"),
            );
            return;
        }
        samples.push(Sample {
            run,
            position,
            value,
        });
    }
    if !draft.errors.is_empty() {
        return;
    }
    if samples.is_empty() {
        at_line(
            &mut draft.errors,
            header_line,
            "no samples after the header",
        );
        return;
    }
    // Every cell (run × position) is built, empty or not: at most
    // MAX_RUNS × MAX_POSITIONS of them, fewer than the samples allowed.
    const _: () = assert!(MAX_RUNS * MAX_POSITIONS <= MAX_TOTAL_SAMPLES);
    let mut runs: Vec<Vec<Reading>> =
        vec![vec![Reading::Samples(Vec::new()); positions.len()]; run_names.len()];
    for s in samples {
        let reading = &mut runs[s.run as usize][s.position as usize];
        match s.value {
            Cell::Summary(summary) => *reading = Reading::Summary(summary),
            Cell::Sample(x) => {
                // A file's rows are all samples or all summaries (the header).
                if let Reading::Samples(xs) = reading {
                    xs.push(x);
                }
            }
        }
    }
    if lonely(
        &positions,
        &first_line,
        &run_names,
        &runs,
        &mut draft.errors,
    ) {
        return;
    }
    for (name, readings) in run_names.iter().zip(&runs) {
        for (p, cell) in readings.iter().enumerate() {
            if cell.count() == 0 {
                draft.errors.add(
                    Loc::Root,
                    format!(
                        "CSV: run `{}` has no samples at position {p} ({})",
                        echo(name),
                        describe(&positions[p])
                    ),
                );
            }
        }
    }
    let mut drafts = Vec::with_capacity(runs.len());
    for (r, readings) in runs.into_iter().enumerate() {
        let each: Vec<Option<f64>> = (0..positions.len() as u32)
            .map(|p| cell_temperatures.get(&(r as u32, p)).copied().flatten())
            .collect();
        let (temperature_c, position_temperatures_c) = match run_temperature(&each) {
            Ok(t) => t,
            Err(why) => {
                draft.errors.add(
                    Loc::Root,
                    format!("CSV: run `{}` {why}", echo(&run_names[r])),
                );
                (None, None)
            }
        };
        drafts.push(Some(RunDraft {
            readings,
            temperature_c,
            position_temperatures_c,
        }));
    }
    draft.positions = Slot::Value(positions.into_iter().map(Some).collect());
    draft.runs = Slot::Value(drafts);
}

/// A run's temperature from its positions' (`each`, none where a row gave
/// none): the one they share, or, when they differ, their mean with each
/// kept — every position then needs one.
fn run_temperature(each: &[Option<f64>]) -> Result<(Option<f64>, Option<Vec<f64>>), String> {
    let first = each.first().copied().flatten();
    if each.iter().all(|t| *t == first) {
        return Ok((first, None));
    }
    let Some(ts) = each.iter().copied().collect::<Option<Vec<f64>>>() else {
        return Err(
            "gives `temperature_c` at some positions and not at others: give the run's, or one \
             per position"
                .to_owned(),
        );
    };
    Ok((Some(ts.iter().sum::<f64>() / ts.len() as f64), Some(ts)))
}

/// With three runs or more, a position that only one run has — among
/// positions the runs mostly share — is most likely a typo in that line (89
/// for 90): blamed on the line it first appears on,
/// with the nearest position the other runs share — not on every other run
/// for lacking it. True when any was found.
fn lonely(
    positions: &[PositionDraft],
    first_line: &[usize],
    run_names: &[String],
    runs: &[Vec<Reading>],
    errors: &mut Errors,
) -> bool {
    if run_names.len() < 3 {
        return false;
    }
    let holders = |p: usize| runs.iter().filter(|r| r[p].count() > 0).count();
    let shared: Vec<usize> = (0..positions.len()).filter(|&p| holders(p) > 1).collect();
    let alone: Vec<usize> = (0..positions.len()).filter(|&p| holders(p) == 1).collect();
    // Typos are the exception: when most positions are one run's alone, the
    // runs simply do not share positions, and each missing cell is said.
    if alone.is_empty() || alone.len() > shared.len() {
        return false;
    }
    let mut found = false;
    for p in alone {
        let Some(run) = runs.iter().position(|r| r[p].count() > 0) else {
            continue;
        };
        let nearest = positions[p].angle_deg.and_then(|a| {
            shared
                .iter()
                .filter_map(|&q| positions[q].angle_deg)
                .min_by(|x, y| (x - a).abs().total_cmp(&(y - a).abs()))
        });
        let near = nearest.map_or(String::new(), |n| format!(" — {n}°, as in the others?"));
        at_line(
            errors,
            first_line[p],
            format!(
                "position ({}) appears in run `{}` only; every run must have the same \
                 positions{near}",
                describe(&positions[p]),
                echo(&run_names[run])
            ),
        );
        found = true;
    }
    found
}

fn describe(position: &PositionDraft) -> String {
    let mut parts = Vec::new();
    if let Some(a) = position.angle_deg {
        parts.push(format!("angle_deg {a}"));
    }
    if let Some(a) = position.a {
        parts.push(format!("a {:?}", a.to_array()));
    }
    if let Some(l) = &position.label {
        parts.push(format!("label {}", echo(l)));
    }
    parts.join(", ")
}
