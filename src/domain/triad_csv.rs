//! Triad submissions as CSV (RFC 4180, the `csv` crate), read into the
//! same [`TriadBody`] as JSON. `# key: value` lines before the header carry
//! `sensor_id`, `station_id`, `performed_at`, `sensor_type`, `unit`,
//! `gravity_rel_std`, with known orientations `batches`, `second_order` and
//! the stand's `angle_std_arcsec`, and for a recording `rate_hz` and the
//! detector's `still_s`, `window_s`, `threshold`, `min_static_s`; the
//! header chooses the form:
//!
//! ```text
//! u_x,u_y,u_z                      a recording (needs `# rate_hz:`)
//! position,u_x,u_y,u_z             static positions of unknown orientation
//! run,g_x,g_y,g_z,u_x,u_y,u_z      known orientations, one sample a row
//! ```
//!
//! Every layout may end with a `temperature_c` column, for a temperature
//! model: a recording's is each sample's; static positions' and runs' the
//! same on every row of a position (a position's temperature; refused,
//! naming the line, where it differs within one), and a run whose positions
//! differ gives one per position (a chamber that drifts), else the run's.
//!
//! Static positions and runs are numbered in order of first appearance by
//! their `position` or `run` value; with known orientations each run's
//! positions are its distinct gravity vectors in order of first appearance,
//! and every run must visit the first run's positions in the same order.
//! Problems with the layout or a row name the CSV line.

use std::collections::HashMap;

use super::field::{Errors, Invalid, Loc};
use super::limits::MAX_TOTAL_SAMPLES;
use super::triad::{
    DetectorBody, OrientationsBody, RecordingBody, RunTemperature, TriadBody, TriadRunBody,
    TriadStandBody,
};

/// The three headers.
const RECORDING: [&str; 3] = ["u_x", "u_y", "u_z"];
const STATIC: [&str; 4] = ["position", "u_x", "u_y", "u_z"];
const KNOWN: [&str; 7] = ["run", "g_x", "g_y", "g_z", "u_x", "u_y", "u_z"];
/// The column a temperature model's layouts end with.
const TEMPERATURE: &str = "temperature_c";

/// Whether `columns` are `layout`, with the temperature column (`Some(true)`)
/// or without (`Some(false)`).
fn layout(columns: &[&str], layout: &[&str]) -> Option<bool> {
    match columns.split_last() {
        _ if columns == layout => Some(false),
        Some((&last, rest)) if last == TEMPERATURE && rest == layout => Some(true),
        _ => None,
    }
}

/// A position's temperature: the one on its first row, each later row of
/// it (on `line`, reading `t`) the same, else an error naming the line.
fn same(kept: &mut Option<f64>, t: f64, line: u64, errors: &mut Errors) {
    match kept {
        None => *kept = Some(t),
        Some(k) if *k == t => {}
        Some(k) => at_line(
            errors,
            line,
            format!(
                "`temperature_c` {t} differs from {k} on the position's earlier rows: one \
                 temperature a position"
            ),
        ),
    }
}

fn at_line(errors: &mut Errors, line: u64, detail: impl std::fmt::Display) {
    errors.add(Loc::Root, format!("CSV line {line}: {detail}"));
}

/// A number on line `line` (0 after reporting a problem).
fn value(line: u64, text: &str, errors: &mut Errors) -> f64 {
    text.parse::<f64>().unwrap_or_else(|_| {
        at_line(
            errors,
            line,
            format!("`{}` is not a number", crate::domain::text::echo(text)),
        );
        0.0
    })
}

/// Three numbers on line `line`.
/// The stand of a fit from the gravity magnitude: its gravity alone.
fn gravity_only(gravity_rel_std: Option<f64>) -> Option<TriadStandBody> {
    gravity_rel_std.map(|g| TriadStandBody {
        angle_std_arcsec: None,
        gravity_rel_std: Some(g),
    })
}

fn triple(line: u64, f: &[String], errors: &mut Errors) -> [f64; 3] {
    [
        value(line, &f[0], errors),
        value(line, &f[1], errors),
        value(line, &f[2], errors),
    ]
}

/// A run's positions (gravity vectors, in order of first appearance) and
/// each position's samples.
type Visits = (Vec<[f64; 3]>, Vec<Vec<[f64; 3]>>);

/// Reads a triad CSV into the JSON body's shape.
pub fn read(text: &str) -> Result<TriadBody, Invalid> {
    let mut errors = Errors::default();
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut meta: HashMap<String, (u64, String)> = HashMap::new();
    let mut body_start = 0;
    let mut line_no = 0u64;
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            line_no += 1;
            body_start += line.len();
            if let Some((key, value)) = trimmed.trim_start_matches('#').split_once(':') {
                let key = key.trim().to_owned();
                if meta
                    .insert(key.clone(), (line_no, value.trim().to_owned()))
                    .is_some()
                {
                    at_line(&mut errors, line_no, format!("`{key}` is given twice"));
                }
            }
            continue;
        }
        break;
    }
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(&text.as_bytes()[body_start..]);
    let header: Vec<String> = match reader.headers() {
        Ok(h) => h.iter().map(str::to_owned).collect(),
        Err(e) => {
            at_line(&mut errors, line_no + 1, e);
            return Err(errors.into_invalid());
        }
    };
    let header_line = line_no + 1;
    let columns: Vec<&str> = header.iter().map(String::as_str).collect();
    let number = |key: &str, errors: &mut Errors| -> Option<f64> {
        let (line, v) = meta.get(key)?;
        match v.parse::<f64>() {
            Ok(x) => Some(x),
            Err(_) => {
                at_line(errors, *line, format!("`{key}` must be a number"));
                None
            }
        }
    };
    let mut rows: Vec<(u64, Vec<String>)> = Vec::new();
    for record in reader.records() {
        match record {
            Ok(r) => {
                let line = header_line + r.position().map_or(0, |p| p.line() - 1);
                if r.len() != columns.len() {
                    at_line(
                        &mut errors,
                        line,
                        format!("has {} fields; the header has {}", r.len(), columns.len()),
                    );
                    continue;
                }
                rows.push((line, r.iter().map(str::to_owned).collect()));
                if rows.len() > MAX_TOTAL_SAMPLES {
                    at_line(
                        &mut errors,
                        line,
                        format!("more than {MAX_TOTAL_SAMPLES} samples"),
                    );
                    return Err(errors.into_invalid());
                }
            }
            Err(e) => at_line(&mut errors, header_line, e),
        }
    }
    let mut body = TriadBody {
        sensor_id: meta.get("sensor_id").map(|(_, v)| v.clone()),
        station_id: meta.get("station_id").map(|(_, v)| v.clone()),
        performed_at: meta.get("performed_at").map(|(_, v)| v.clone()),
        sensor_type: meta.get("sensor_type").map(|(_, v)| v.clone()),
        stand: None,
        standards: None,
        second_order: None,
        unit: meta.get("unit").map(|(_, v)| v.clone()),
        orientations: None,
        runs: None,
        batches: None,
        static_positions: None,
        static_temperatures_c: None,
        recording: None,
    };
    let allowed: &[&str] = if let Some(with_t) = layout(&columns, &RECORDING) {
        let samples = rows
            .iter()
            .map(|(l, f)| triple(*l, &f[..3], &mut errors))
            .collect();
        let temperature_c = with_t.then(|| {
            rows.iter()
                .map(|(l, f)| value(*l, &f[3], &mut errors))
                .collect()
        });
        let detector = DetectorBody {
            still_s: number("still_s", &mut errors),
            window_s: number("window_s", &mut errors),
            threshold: number("threshold", &mut errors),
            min_static_s: number("min_static_s", &mut errors),
        };
        body.stand = gravity_only(number("gravity_rel_std", &mut errors));
        match number("rate_hz", &mut errors) {
            Some(rate_hz) => {
                body.recording = Some(RecordingBody {
                    rate_hz,
                    samples,
                    detector: Some(detector),
                    temperature_c,
                })
            }
            None => at_line(
                &mut errors,
                header_line,
                "a recording needs `# rate_hz: …` before the header",
            ),
        }
        &[
            "sensor_id",
            "station_id",
            "performed_at",
            "sensor_type",
            "unit",
            "rate_hz",
            "still_s",
            "window_s",
            "threshold",
            "min_static_s",
            "gravity_rel_std",
        ]
    } else if let Some(with_t) = layout(&columns, &STATIC) {
        let mut order: HashMap<String, usize> = HashMap::new();
        let mut positions: Vec<Vec<[f64; 3]>> = Vec::new();
        let mut temperatures: Vec<Option<f64>> = Vec::new();
        for (line, f) in &rows {
            let next = order.len();
            let p = *order.entry(f[0].clone()).or_insert(next);
            if p == positions.len() {
                positions.push(Vec::new());
                temperatures.push(None);
            }
            positions[p].push(triple(*line, &f[1..4], &mut errors));
            if with_t {
                let t = value(*line, &f[4], &mut errors);
                same(&mut temperatures[p], t, *line, &mut errors);
            }
        }
        body.static_positions = Some(positions);
        if with_t {
            body.static_temperatures_c = temperatures.into_iter().collect();
        }
        body.stand = gravity_only(number("gravity_rel_std", &mut errors));
        &[
            "sensor_id",
            "station_id",
            "performed_at",
            "sensor_type",
            "unit",
            "gravity_rel_std",
        ]
    } else if let Some(with_t) = layout(&columns, &KNOWN) {
        known(&rows, with_t, &mut body, &mut errors);
        body.batches = number("batches", &mut errors).map(|b| b as usize);
        body.second_order = match meta.get("second_order") {
            None => None,
            Some((_, v)) if v == "true" => Some(true),
            Some((_, v)) if v == "false" => Some(false),
            Some((line, _)) => {
                at_line(&mut errors, *line, "`second_order` must be true or false");
                None
            }
        };
        let angle_std_arcsec = number("angle_std_arcsec", &mut errors);
        let gravity_rel_std = number("gravity_rel_std", &mut errors);
        if angle_std_arcsec.is_some() || gravity_rel_std.is_some() {
            body.stand = Some(TriadStandBody {
                angle_std_arcsec,
                gravity_rel_std,
            });
        }
        &[
            "sensor_id",
            "station_id",
            "performed_at",
            "sensor_type",
            "unit",
            "batches",
            "angle_std_arcsec",
            "gravity_rel_std",
            "second_order",
        ]
    } else {
        at_line(
            &mut errors,
            header_line,
            "the header must be `u_x,u_y,u_z` (a recording), `position,u_x,u_y,u_z` (static \
             positions) or `run,g_x,g_y,g_z,u_x,u_y,u_z` (known orientations), each \
             optionally ending with `temperature_c`",
        );
        &[]
    };
    for (key, (line, _)) in &meta {
        if !allowed.contains(&key.as_str()) && !allowed.is_empty() {
            at_line(
                &mut errors,
                *line,
                format!(
                    "`{}` is not known for this layout; expected one of {}",
                    crate::domain::text::echo(key),
                    allowed.join(", ")
                ),
            );
        }
    }
    errors.finish(|| body)
}

/// Known orientations: runs by `run`, positions by gravity vector; with
/// `with_t`, each position's temperature from the last column (module doc).
fn known(rows: &[(u64, Vec<String>)], with_t: bool, body: &mut TriadBody, errors: &mut Errors) {
    let mut run_order: HashMap<String, usize> = HashMap::new();
    // Per run: its positions' vectors in order, and their samples.
    let mut runs: Vec<Visits> = Vec::new();
    // Per run: each position's temperature.
    let mut temperatures: Vec<Vec<Option<f64>>> = Vec::new();
    for (line, f) in rows {
        let next = run_order.len();
        let j = *run_order.entry(f[0].clone()).or_insert(next);
        if j == runs.len() {
            runs.push((Vec::new(), Vec::new()));
            temperatures.push(Vec::new());
        }
        let g = triple(*line, &f[1..4], errors);
        let u = triple(*line, &f[4..7], errors);
        let (gs, samples) = &mut runs[j];
        let p = match gs.iter().position(|x| *x == g) {
            Some(p) => {
                samples[p].push(u);
                p
            }
            None => {
                gs.push(g);
                samples.push(vec![u]);
                temperatures[j].push(None);
                gs.len() - 1
            }
        };
        if with_t {
            let t = value(*line, &f[7], errors);
            same(&mut temperatures[j][p], t, *line, errors);
        }
    }
    let Some((first, _)) = runs.first() else {
        errors.add(Loc::Root, "no samples after the header");
        return;
    };
    for (j, (gs, _)) in runs.iter().enumerate().skip(1) {
        if gs != first {
            errors.add(
                Loc::Root,
                format!(
                    "run {} visits other positions, or in another order, than the first run",
                    j + 1
                ),
            );
        }
    }
    body.orientations = Some(OrientationsBody::Vectors(first.clone()));
    body.runs = Some(
        runs.into_iter()
            .zip(temperatures)
            .map(|((_, samples), ts)| TriadRunBody {
                samples,
                temperature_c: run_temperature(ts),
            })
            .collect(),
    );
}

/// A run's temperature from its positions' (none without the column):
/// the run's when they agree, else one per position.
fn run_temperature(ts: Vec<Option<f64>>) -> Option<RunTemperature> {
    let ts: Vec<f64> = ts.into_iter().collect::<Option<_>>()?;
    match ts.first() {
        Some(&t) if ts.iter().all(|x| *x == t) => Some(RunTemperature::One(t)),
        Some(_) => Some(RunTemperature::Each(ts)),
        None => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_three_layouts_read_into_the_json_shape() {
        let rec = read(
            "# rate_hz: 50\n# unit: m/s2\n# window_s: 0.5\nu_x,u_y,u_z\n0.1,0.2,9.8\n0.1,0.2,9.9\n",
        )
        .unwrap();
        let r = rec.recording.unwrap();
        assert_eq!((r.rate_hz, r.samples.len()), (50.0, 2));
        assert_eq!(r.detector.unwrap().window_s, Some(0.5));
        assert_eq!(rec.unit.as_deref(), Some("m/s2"));
        let st = read("position,u_x,u_y,u_z\nA,1,0,0\nB,0,1,0\nA,1.5,0,0\n").unwrap();
        assert_eq!(
            st.static_positions.unwrap(),
            vec![
                vec![[1.0, 0.0, 0.0], [1.5, 0.0, 0.0]],
                vec![[0.0, 1.0, 0.0]]
            ]
        );
        let kn = read(
            "# batches: 1\nrun,g_x,g_y,g_z,u_x,u_y,u_z\n1,1,0,0,9.8,0,0\n1,0,1,0,0,9.8,0\n2,1,0,0,9.7,0,0\n2,0,1,0,0,9.9,0\n",
        )
        .unwrap();
        assert!(matches!(kn.orientations, Some(OrientationsBody::Vectors(ref v)) if v.len() == 2));
        let runs = kn.runs.unwrap();
        assert_eq!(
            runs[1].samples,
            vec![vec![[9.7, 0.0, 0.0]], vec![[0.0, 9.9, 0.0]]]
        );
        assert_eq!(kn.batches, Some(1));
    }

    #[test]
    fn a_temperature_column_gives_each_position_its_temperature() {
        let st = read("position,u_x,u_y,u_z,temperature_c\nA,1,0,0,20\nB,0,1,0,40\nA,1.5,0,0,20\n")
            .unwrap();
        assert_eq!(st.static_temperatures_c, Some(vec![20.0, 40.0]));
        let kn = read(
            "run,g_x,g_y,g_z,u_x,u_y,u_z,temperature_c\n1,1,0,0,9.8,0,0,20\n1,0,1,0,0,9.8,0,20\n\
             2,1,0,0,9.7,0,0,40\n2,1,0,0,9.7,0,0,40\n2,0,1,0,0,9.9,0,40.5\n",
        )
        .unwrap();
        let runs = kn.runs.unwrap();
        assert_eq!(runs[0].temperature_c, Some(RunTemperature::One(20.0)));
        assert_eq!(
            runs[1].temperature_c,
            Some(RunTemperature::Each(vec![40.0, 40.5]))
        );
        let rec =
            read("# rate_hz: 10\nu_x,u_y,u_z,temperature_c\n0,0,9.8,20.5\n0,0,9.7,20.6\n").unwrap();
        let r = rec.recording.unwrap();
        assert_eq!(r.temperature_c, Some(vec![20.5, 20.6]));
        assert_eq!(r.samples[1], [0.0, 0.0, 9.7]);
        let e = read("position,u_x,u_y,u_z,temperature_c\nA,1,0,0,20\nA,1,0,0,21\n").unwrap_err();
        assert!(
            format!("{e:?}").contains("CSV line 3: `temperature_c` 21 differs from 20"),
            "{e:?}"
        );
    }

    #[test]
    fn problems_name_the_line() {
        let e = read("# rate_hz: fast\nu_x,u_y,u_z\n1,2,x\n").unwrap_err();
        let text = format!("{e:?}");
        assert!(
            text.contains("CSV line 1: `rate_hz` must be a number"),
            "{text}"
        );
        assert!(text.contains("CSV line 3: `x` is not a number"), "{text}");
        let e = read("a,b\n1,2\n").unwrap_err();
        assert!(format!("{e:?}").contains("the header must be"));
        let e = read("# colour: red\nposition,u_x,u_y,u_z\nA,1,0,0\n").unwrap_err();
        assert!(format!("{e:?}").contains("`colour` is not known"));
        let e = read("run,g_x,g_y,g_z,u_x,u_y,u_z\n1,1,0,0,1,0,0\n2,0,1,0,0,1,0\n").unwrap_err();
        assert!(format!("{e:?}").contains("run 2 visits other positions"));
        let e = read("u_x,u_y,u_z\n1,2,3\n").unwrap_err();
        assert!(format!("{e:?}").contains("needs `# rate_hz"));
    }
}
