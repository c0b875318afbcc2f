//! The CSV submission layout, converted to the JSON submission form.
//!
//! ```text
//! # sensor_id: ACC-0042
//! # unit: mA
//! # model: k0 ki kp
//! # batches: 2
//! run,angle_deg,direction,output
//! 1,0,cw,0.005341914
//! 1,0,ccw,0.005679272
//! 1,90,cw,1.215466211
//! ...
//! ```
//!
//! * `# key: value` lines carry the submission's other fields (`sensor_id`,
//!   `station_id`, `performed_at`, `unit`, `model` — terms separated by spaces
//!   or commas —, `mount`, `batches`, `notes`); other `#` lines and blank lines
//!   are ignored.
//! * The first other line is the header. Columns, in any order: `run` (or
//!   `test`), the position as `angle_deg` or as `a_i`, `a_p`, `a_o` (or
//!   both), optional `label`, optional `direction` (informational), and
//!   `output`. Fields may be double-quoted (RFC 4180).
//! * Each row is one sample. Positions are numbered in order of first
//!   appearance, runs likewise; every run must have samples at every position.
//!
//! Errors name the CSV line. Checks on values (ranges, identifiability) are
//! those of the JSON form and point into it: `/runs/2` is the third run to
//! appear in the file.

use serde_json::{Map, Value, json};

use super::FieldError;
use crate::submission::FIELDS;

/// The submission fields a `# key: value` line may set: all but the two the
/// rows themselves make up.
fn is_metadata(key: &str) -> bool {
    FIELDS.contains(&key) && !matches!(key, "positions" | "runs")
}

const COLUMNS: &[&str] = &[
    "run",
    "test",
    "angle_deg",
    "a_i",
    "a_p",
    "a_o",
    "label",
    "direction",
    "output",
];

fn line_error(line: usize, detail: impl std::fmt::Display) -> FieldError {
    FieldError {
        pointer: String::new(),
        detail: format!("CSV line {line}: {detail}"),
    }
}

/// Splits one CSV record, honouring double quotes.
fn split_record(line: &str) -> Result<Vec<String>, &'static str> {
    let mut fields = Vec::new();
    let mut field = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    let mut was_quoted = false;
    while let Some(ch) = chars.next() {
        match (quoted, ch) {
            (true, '"') if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            (true, '"') => quoted = false,
            (true, c) => field.push(c),
            (false, '"') if field.trim().is_empty() && !was_quoted => {
                field.clear();
                quoted = true;
                was_quoted = true;
            }
            (false, '"') => return Err("a quote inside an unquoted field"),
            (false, ',') => {
                fields.push(std::mem::take(&mut field));
                was_quoted = false;
            }
            (false, c) => field.push(c),
        }
    }
    if quoted {
        return Err("an unterminated quoted field");
    }
    fields.push(field);
    Ok(fields.into_iter().map(|f| f.trim().to_owned()).collect())
}

fn finite(s: &str) -> Option<f64> {
    s.parse::<f64>().ok().filter(|x| x.is_finite())
}

/// Converts a CSV submission to its JSON form.
pub fn to_json(text: &str) -> Result<Value, Vec<FieldError>> {
    let mut errors = Vec::new();
    let mut body = Map::new();
    let mut header: Option<Vec<String>> = None;
    // position key → index; run name → index; readings[run][position]
    let mut positions: Vec<(String, Value)> = Vec::new();
    let mut runs: Vec<(String, Vec<Vec<Value>>)> = Vec::new();

    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let trimmed = raw.trim();
        if trimmed.is_empty() {
            continue;
        }
        if let Some(comment) = trimmed.strip_prefix('#') {
            if let Some((key, value)) = comment.split_once(':') {
                let (key, value) = (key.trim(), value.trim());
                if !is_metadata(key) {
                    if key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                        let known: Vec<&str> =
                            FIELDS.iter().copied().filter(|f| is_metadata(f)).collect();
                        errors.push(line_error(
                            line,
                            format!(
                                "unknown field `{key}`; expected one of: {}",
                                known.join(", ")
                            ),
                        ));
                    }
                    continue;
                }
                if body.contains_key(key) {
                    errors.push(line_error(line, format!("`{key}` is given twice")));
                    continue;
                }
                let v = match key {
                    "model" => Value::Array(
                        value
                            .split([',', ' ', '\t'])
                            .filter(|t| !t.is_empty())
                            .map(|t| Value::String(t.to_owned()))
                            .collect(),
                    ),
                    "batches" => value
                        .parse::<u64>()
                        .map_or_else(|_| Value::String(value.to_owned()), Value::from),
                    _ => Value::String(value.to_owned()),
                };
                body.insert(key.to_owned(), v);
            }
            continue;
        }
        let fields = match split_record(raw) {
            Ok(f) => f,
            Err(why) => {
                errors.push(line_error(line, why));
                continue;
            }
        };
        let Some(cols) = &header else {
            let cols: Vec<String> = fields.iter().map(|f| f.to_ascii_lowercase()).collect();
            for c in &cols {
                if !COLUMNS.contains(&c.as_str()) {
                    errors.push(line_error(
                        line,
                        format!("unknown column `{c}`; expected: {}", COLUMNS.join(", ")),
                    ));
                }
            }
            let has = |c: &str| cols.iter().any(|x| x == c);
            if !has("output") {
                errors.push(line_error(line, "the header needs an `output` column"));
            }
            if !has("run") && !has("test") {
                errors.push(line_error(line, "the header needs a `run` column"));
            }
            let explicit = ["a_i", "a_p", "a_o"].iter().filter(|c| has(c)).count();
            if explicit != 0 && explicit != 3 {
                errors.push(line_error(line, "give all of `a_i`, `a_p`, `a_o` or none"));
            }
            if !has("angle_deg") && explicit == 0 {
                errors.push(line_error(
                    line,
                    "the header needs `angle_deg` or `a_i`, `a_p`, `a_o` columns",
                ));
            }
            for (k, c) in cols.iter().enumerate() {
                if cols[..k].contains(c) {
                    errors.push(line_error(line, format!("column `{c}` appears twice")));
                }
            }
            if !errors.is_empty() {
                return Err(errors);
            }
            header = Some(cols);
            continue;
        };
        if fields.len() != cols.len() {
            errors.push(line_error(
                line,
                format!("has {} fields, the header {}", fields.len(), cols.len()),
            ));
            continue;
        }
        let get = |c: &str| cols.iter().position(|x| x == c).map(|k| fields[k].as_str());
        let run = get("run").or_else(|| get("test")).unwrap_or_default();
        if run.is_empty() {
            errors.push(line_error(line, "the run is empty"));
            continue;
        }
        let Some(output) = get("output").and_then(finite) else {
            errors.push(line_error(line, "`output` must be a finite number"));
            continue;
        };
        let mut position = Map::new();
        let mut key = String::new();
        if let Some(angle) = get("angle_deg") {
            let Some(deg) = finite(angle) else {
                errors.push(line_error(line, "`angle_deg` must be a finite number"));
                continue;
            };
            position.insert("angle_deg".into(), json!(deg));
            key += &format!("{deg}|");
        }
        if get("a_i").is_some() {
            let a: Option<Vec<f64>> = ["a_i", "a_p", "a_o"]
                .iter()
                .map(|c| get(c).and_then(finite))
                .collect();
            let Some(a) = a else {
                errors.push(line_error(
                    line,
                    "`a_i`, `a_p`, `a_o` must be finite numbers",
                ));
                continue;
            };
            key += &format!("{a:?}|");
            position.insert("a".into(), json!(a));
        }
        if let Some(label) = get("label").filter(|l| !l.is_empty()) {
            key += label;
            position.insert("label".into(), json!(label));
        }
        let p = match positions.iter().position(|(k, _)| *k == key) {
            Some(p) => p,
            None => {
                positions.push((key, Value::Object(position)));
                for (_, readings) in &mut runs {
                    readings.push(Vec::new());
                }
                positions.len() - 1
            }
        };
        let r = match runs.iter().position(|(name, _)| name == run) {
            Some(r) => r,
            None => {
                runs.push((run.to_owned(), vec![Vec::new(); positions.len()]));
                runs.len() - 1
            }
        };
        runs[r].1[p].push(json!(output));
    }
    if header.is_none() && errors.is_empty() {
        errors.push(line_error(
            text.lines().count().max(1),
            "no header line and no samples",
        ));
    }
    for (name, readings) in &runs {
        for (p, samples) in readings.iter().enumerate() {
            if samples.is_empty() {
                errors.push(FieldError {
                    pointer: String::new(),
                    detail: format!(
                        "CSV: run `{name}` has no samples at position {p} ({})",
                        positions[p].1
                    ),
                });
            }
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    body.insert(
        "positions".into(),
        Value::Array(positions.into_iter().map(|(_, v)| v).collect()),
    );
    body.insert(
        "runs".into(),
        Value::Array(
            runs.into_iter()
                .map(|(_, readings)| json!({ "readings": readings }))
                .collect(),
        ),
    );
    Ok(Value::Object(body))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_table_converts_like_the_json_example() {
        let csv = format!(
            "# sensor_id: PAPER-2005\n# model: k0, ki, kp\n# batches: 2\n{}",
            include_str!("../../core/tests/data/table1.csv")
        );
        let v = to_json(&csv).unwrap();
        assert_eq!(v["sensor_id"], "PAPER-2005");
        assert_eq!(v["model"], json!(["k0", "ki", "kp"]));
        assert_eq!(v["batches"], 2);
        assert_eq!(v["positions"].as_array().unwrap().len(), 4);
        assert_eq!(
            v["positions"][1],
            json!({"angle_deg": 90.0, "a": [-1.0, 0.0, 0.0]})
        );
        assert_eq!(v["runs"].as_array().unwrap().len(), 6);
        assert_eq!(
            v["runs"][0]["readings"][0],
            json!([0.005341914, 0.005679272])
        );
    }

    #[test]
    fn quoted_fields_and_crlf() {
        assert_eq!(
            split_record(r#"1,"a, ""b""",3"#).unwrap(),
            ["1", "a, \"b\"", "3"]
        );
        assert!(split_record(r#"1,"open"#).is_err());
        let v = to_json("run,angle_deg,label,output\r\n1,0,\"up, north\",1.5\r\n").unwrap();
        assert_eq!(v["positions"][0]["label"], "up, north");
    }

    #[test]
    fn errors_name_lines() {
        let e = to_json("run,angle,output\n").unwrap_err();
        assert!(
            e[0].detail
                .starts_with("CSV line 1: unknown column `angle`"),
            "{e:?}"
        );
        let e = to_json("run,angle_deg,output\n1,0,1.0\n1,90,NaN\n1,180\n").unwrap_err();
        assert_eq!(e.len(), 2);
        assert!(e[0].detail.starts_with("CSV line 3"), "{e:?}");
        assert!(e[1].detail.starts_with("CSV line 4"), "{e:?}");
        let e = to_json("run,angle_deg,output\n1,0,1\n1,90,2\n2,0,1\n").unwrap_err();
        assert!(
            e[0].detail.contains("run `2` has no samples at position 1"),
            "{e:?}"
        );
        let e = to_json("# sensor: x\n").unwrap_err();
        assert!(e[0].detail.contains("unknown field `sensor`"), "{e:?}");
        assert!(to_json("").is_err());
    }
}
