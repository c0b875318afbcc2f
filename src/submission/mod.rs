//! Tumble-test submissions: the request body checked field by field, turned
//! into the core's [`TumbleTest`] and calibrated.
//!
//! This is the one place where the wire format meets the core ("parse, don't
//! validate"): [`evaluate`] either returns a calibrated [`Evaluated`] or every
//! problem it found, each with the JSON pointer of the offending value.
//! The limits below are part of the API contract (see `openapi.yaml`).

mod result;

pub use result::{PositionOut, ResultView};

use accelcal_core::{
    Calibration, Error as CoreError, FusionError, Gravity, Model, Mount, Position, Run, Term,
    TumbleTest,
};
use serde_json::Value;

use crate::input::check::{Chars, optional};
use crate::input::{Checker, FieldError, Ptr};
use crate::timestamp::Timestamp;

/// Longest identifier (`sensor_id`, `station_id`), in characters.
pub const MAX_ID_CHARS: usize = 64;
/// Longest `unit`.
pub const MAX_UNIT_CHARS: usize = 32;
/// Longest position label.
pub const MAX_LABEL_CHARS: usize = 64;
/// Longest `notes`.
pub const MAX_NOTES_CHARS: usize = 4096;
/// Most positions in one tumble.
pub const MAX_POSITIONS: usize = 360;
/// Most runs in one submission.
pub const MAX_RUNS: usize = 1000;
/// Most samples at one position of one run.
pub const MAX_SAMPLES: usize = 1000;
/// Most samples in one submission, over all runs and positions.
pub const MAX_TOTAL_SAMPLES: usize = 200_000;
/// Most batches.
pub const MAX_BATCHES: u64 = 100;
/// Largest magnitude of a reading, in the output's unit.
pub const MAX_READING: f64 = 1e9;
/// Largest magnitude of a dividing-head angle, in degrees.
pub const MAX_ANGLE_DEG: f64 = 3600.0;
/// Accepted norm of explicit gravity components: a tumble in the 1 g field.
pub const GRAVITY_NORM: std::ops::RangeInclusive<f64> = 0.9..=1.1;
/// How far in the future `performed_at` may lie (clock skew), in seconds;
/// it may not lie before 1970 either.
pub const MAX_FUTURE_SECONDS: i64 = 24 * 3600;

/// The members of a submission object.
pub const FIELDS: &[&str] = &[
    "sensor_id",
    "station_id",
    "performed_at",
    "unit",
    "model",
    "mount",
    "positions",
    "runs",
    "batches",
    "notes",
];

/// A position as submitted and resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct PositionIn {
    /// The dividing-head angle, when given.
    pub angle_deg: Option<f64>,
    /// The resolved gravity components.
    pub a: Gravity,
    /// The label, when given.
    pub label: Option<String>,
}

/// A checked submission.
#[derive(Clone, Debug)]
pub struct Submission {
    /// The sensor calibrated.
    pub sensor_id: String,
    /// The station named in the body, if any (the token may bind another).
    pub station_id: Option<String>,
    /// When the test was performed, if given.
    pub performed_at: Option<Timestamp>,
    /// Unit of the outputs.
    pub unit: String,
    /// Mount used for angles.
    pub mount: Mount,
    /// Positions, resolved.
    pub positions: Vec<PositionIn>,
    /// Number of fusion batches.
    pub batches: usize,
    /// Free text.
    pub notes: Option<String>,
    /// The tumble test handed to the core.
    pub test: TumbleTest,
}

/// A submission with its calibration.
#[derive(Clone, Debug)]
pub struct Evaluated {
    /// The checked submission.
    pub submission: Submission,
    /// Per-run and fused results.
    pub calibration: Calibration,
}

/// Checks, identifies and fuses a submission body (already parsed JSON).
pub fn evaluate(body: &Value, now: Timestamp) -> Result<Evaluated, Vec<FieldError>> {
    let submission = check(body, now)?;
    let calibration = submission
        .test
        .calibrate(submission.batches)
        .map_err(|e| vec![core_error(&e, body)])?;
    Ok(Evaluated {
        submission,
        calibration,
    })
}

/// The model named in a body, or the default; used by `check`.
fn model(c: &mut Checker, v: Option<&Value>, ptr: &Ptr) -> Option<Model> {
    let Some(v) = v else {
        return Some(Model::default());
    };
    let items = c.array(v, ptr, 1, Term::ALL.len())?;
    let mut terms = Vec::with_capacity(items.len());
    let mut ok = true;
    for (k, item) in items.iter().enumerate() {
        let p = ptr.index(k);
        let Some(name) = item.as_str() else {
            c.error(&p, "must be a term name such as \"k0\"");
            ok = false;
            continue;
        };
        match name.parse::<Term>() {
            Ok(t) if terms.contains(&t) => {
                c.error(&p, format!("term `{t}` is listed twice"));
                ok = false;
            }
            Ok(t) => terms.push(t),
            Err(e) => {
                c.error(&p, e.to_string());
                ok = false;
            }
        }
    }
    ok.then(|| Model::new(terms).expect("checked non-empty and distinct"))
}

fn mount(c: &mut Checker, v: Option<&Value>, ptr: &Ptr) -> Option<Mount> {
    match v.map(|v| v.as_str()) {
        None => Some(Mount::default()),
        Some(Some("pendulum")) => Some(Mount::Pendulum),
        Some(Some("gate")) => Some(Mount::Gate),
        Some(_) => {
            c.error(ptr, "must be \"pendulum\" or \"gate\"");
            None
        }
    }
}

fn position(c: &mut Checker, v: &Value, ptr: &Ptr, mount: Option<Mount>) -> Option<PositionIn> {
    let map = c.object(v, ptr, &["angle_deg", "a", "label"])?;
    let label = optional(map, "label")
        .and_then(|l| c.string(l, &ptr.key("label"), MAX_LABEL_CHARS, Chars::Line));
    let angle =
        optional(map, "angle_deg").map(|a| c.number(a, &ptr.key("angle_deg"), MAX_ANGLE_DEG));
    let explicit = optional(map, "a").map(|a| gravity(c, a, &ptr.key("a")));
    let a = match (angle, explicit) {
        (None, None) => {
            c.error(
                ptr,
                "needs `angle_deg` (with the mount) or `a` (gravity components in g)",
            );
            return None;
        }
        (Some(angle), None) => mount?.gravity(angle?),
        (angle, Some(a)) => {
            let a = a?;
            if let (Some(Some(deg)), Some(m)) = (angle, mount) {
                let from_angle = m.gravity(deg);
                let off = (0..3)
                    .map(|k| (a.to_array()[k] - from_angle.to_array()[k]).abs())
                    .fold(0.0, f64::max);
                if off > 1e-3 {
                    c.error(
                        &ptr.key("a"),
                        format!(
                            "disagrees with angle_deg {deg} on the {} mount, which gives {:?}",
                            mount_name(m),
                            from_angle.to_array()
                        ),
                    );
                    return None;
                }
            }
            a
        }
    };
    Some(PositionIn {
        angle_deg: angle.flatten(),
        a,
        label,
    })
}

fn mount_name(m: Mount) -> &'static str {
    match m {
        Mount::Pendulum => "pendulum",
        Mount::Gate => "gate",
    }
}

fn gravity(c: &mut Checker, v: &Value, ptr: &Ptr) -> Option<Gravity> {
    let items = c.array(v, ptr, 3, 3)?;
    let mut a = [0.0; 3];
    let mut ok = true;
    for (k, item) in items.iter().enumerate() {
        match c.number(item, &ptr.index(k), 10.0) {
            Some(x) => a[k] = x,
            None => ok = false,
        }
    }
    if !ok {
        return None;
    }
    let g = Gravity::from(a);
    if !GRAVITY_NORM.contains(&g.norm()) {
        c.error(
            ptr,
            format!(
                "gravity components [a_i, a_p, a_o] must have a norm near 1 g ({}–{}), not {:.6}",
                GRAVITY_NORM.start(),
                GRAVITY_NORM.end(),
                g.norm()
            ),
        );
        return None;
    }
    Some(g)
}

fn runs(c: &mut Checker, v: &Value, ptr: &Ptr, positions: Option<usize>) -> Option<Vec<Run>> {
    let items = c.array(v, ptr, 1, MAX_RUNS)?;
    let mut out = Vec::with_capacity(items.len());
    let mut total = 0usize;
    for (j, item) in items.iter().enumerate() {
        let p = ptr.index(j);
        let Some(map) = c.object(item, &p, &["readings"]) else {
            continue;
        };
        let Some(readings) = c.required(map, &p, "readings") else {
            continue;
        };
        let rp = p.key("readings");
        let Some(per_position) = c.array(readings, &rp, 1, MAX_POSITIONS) else {
            continue;
        };
        if let Some(n) = positions.filter(|n| *n != per_position.len()) {
            c.error(
                &rp,
                format!(
                    "must hold one array of samples per position: {n} positions, {} given",
                    per_position.len()
                ),
            );
            continue;
        }
        let mut run = Vec::with_capacity(per_position.len());
        for (i, samples) in per_position.iter().enumerate() {
            let sp = rp.index(i);
            let Some(samples) = c.array(samples, &sp, 1, MAX_SAMPLES) else {
                continue;
            };
            total += samples.len();
            let xs: Vec<f64> = samples
                .iter()
                .enumerate()
                .filter_map(|(s, x)| c.number(x, &sp.index(s), MAX_READING))
                .collect();
            run.push(xs);
        }
        out.push(Run { readings: run });
    }
    if total > MAX_TOTAL_SAMPLES {
        c.error(
            ptr,
            format!("holds {total} samples in all; at most {MAX_TOTAL_SAMPLES} are accepted"),
        );
    }
    Some(out)
}

/// Checks every field of a submission and builds the core test.
pub fn check(body: &Value, now: Timestamp) -> Result<Submission, Vec<FieldError>> {
    let mut c = Checker::new();
    let root = Ptr::root();
    let Some(map) = c.object(body, &root, FIELDS) else {
        return Err(c.finish().unwrap_err());
    };
    let field = |k: &str| optional(map, k);

    let sensor_id = c
        .required(map, &root, "sensor_id")
        .and_then(|v| c.string(v, &root.key("sensor_id"), MAX_ID_CHARS, Chars::Identifier));
    let station_id = field("station_id")
        .map(|v| c.string(v, &root.key("station_id"), MAX_ID_CHARS, Chars::Identifier));
    let performed_at = field("performed_at").map(|v| {
        let p = root.key("performed_at");
        let s = c.string(v, &p, 64, Chars::Line)?;
        match Timestamp::parse(&s) {
            Ok(t) if t > now.plus_seconds(MAX_FUTURE_SECONDS) => {
                c.error(
                    &p,
                    "lies more than a day in the future; check the station's clock",
                );
                None
            }
            Ok(t) if t.year() < 1970 => {
                c.error(&p, "lies before 1970; check the station's clock");
                None
            }
            Ok(t) => Some(t),
            Err(e) => {
                c.error(&p, e.to_string());
                None
            }
        }
    });
    let unit = match field("unit") {
        Some(v) => c.string(v, &root.key("unit"), MAX_UNIT_CHARS, Chars::Line),
        None => Some("output".to_owned()),
    };
    let model = model(&mut c, field("model"), &root.key("model"));
    let mount = mount(&mut c, field("mount"), &root.key("mount"));
    let batches = match field("batches") {
        Some(v) => c.integer(v, &root.key("batches"), 1, MAX_BATCHES),
        None => Some(2),
    };
    let notes =
        field("notes").map(|v| c.string(v, &root.key("notes"), MAX_NOTES_CHARS, Chars::Text));

    let positions = c.required(map, &root, "positions").and_then(|v| {
        let p = root.key("positions");
        let items = c.array(v, &p, 1, MAX_POSITIONS)?;
        let n = items.len();
        let out: Vec<PositionIn> = items
            .iter()
            .enumerate()
            .filter_map(|(i, item)| position(&mut c, item, &p.index(i), mount))
            .collect();
        Some((n, out))
    });
    let runs = c.required(map, &root, "runs").and_then(|v| {
        runs(
            &mut c,
            v,
            &root.key("runs"),
            positions.as_ref().map(|p| p.0),
        )
    });

    if !c.is_clean() {
        return Err(c.finish().unwrap_err());
    }
    // Every field is present and valid once the checker is clean.
    let (Some(sensor_id), Some(unit), Some(model), Some(mount), Some(batches)) =
        (sensor_id, unit, model, mount, batches)
    else {
        unreachable!("a missing value is always reported");
    };
    let (_, positions) = positions.expect("reported when missing");
    let runs = runs.expect("reported when missing");
    let core_positions = positions
        .iter()
        .map(|p| Position {
            a: p.a,
            label: p.label.clone(),
        })
        .collect();
    let test =
        TumbleTest::new(model, core_positions, runs).map_err(|e| vec![core_error(&e, body)])?;
    Ok(Submission {
        sensor_id,
        station_id: station_id.flatten(),
        performed_at: performed_at.flatten(),
        unit,
        mount,
        positions,
        batches: batches as usize,
        notes: notes.flatten(),
        test,
    })
}

/// Maps a core refusal to the field it concerns.
pub fn core_error(e: &CoreError, body: &Value) -> FieldError {
    let root = Ptr::root();
    let has = |k: &str| body.get(k).is_some_and(|v| !v.is_null());
    let (ptr, detail) = match e {
        CoreError::RankDeficient { terms, .. } => {
            let names: Vec<&str> = terms.iter().map(|t| t.name()).collect();
            (
                if has("model") {
                    root.key("model")
                } else {
                    root.key("positions")
                },
                format!(
                    "{e}: drop one of {} from the model or add positions that excite them",
                    names.join(", ")
                ),
            )
        }
        CoreError::Fusion {
            source: FusionError::TooFewRuns { batches, .. },
            ..
        } => (
            if has("batches") {
                root.key("batches")
            } else {
                root.key("runs")
            },
            format!(
                "{e}: submit at least {} runs or ask for fewer batches",
                2 * batches
            ),
        ),
        CoreError::Fusion { .. } => (
            root.key("runs"),
            format!("{e}; batch estimation needs runs whose coefficients differ"),
        ),
        CoreError::ReadingCount { run, .. } => {
            (root.key("runs").index(*run).key("readings"), e.to_string())
        }
        CoreError::NoSamples { run, position } => (
            root.key("runs")
                .index(*run)
                .key("readings")
                .index(*position),
            e.to_string(),
        ),
        CoreError::NonFiniteSample {
            run,
            position,
            sample,
        } => (
            root.key("runs")
                .index(*run)
                .key("readings")
                .index(*position)
                .index(*sample),
            e.to_string(),
        ),
        CoreError::NonFiniteGravity { position, .. } => {
            (root.key("positions").index(*position), e.to_string())
        }
        CoreError::NoPositions => (root.key("positions"), e.to_string()),
        CoreError::NoRuns => (root.key("runs"), e.to_string()),
        _ => (root, e.to_string()),
    };
    FieldError {
        pointer: ptr.to_string(),
        detail,
    }
}

#[cfg(test)]
mod tests;
