//! From a [`Draft`] to a [`Submission`]: defaults, the checks that relate
//! fields to each other (positions and mount, readings and positions, the
//! time against the clock), and the core's own refusals mapped to the field
//! they concern.

use accelcal_core::{
    Error as CoreError, FusionError, Model, Mount, Position, Rotation, Run, TumbleTest,
};

use super::draft::{Draft, PositionDraft, Slot};
use super::{PositionIn, StandIn, StandardsIn, Submission};
use crate::domain::field::{Errors, Invalid, Loc};
use crate::domain::limits::{DEFAULT_BATCHES, MAX_FUTURE_SECONDS};
use crate::domain::timestamp::Timestamp;

/// How far `t` lies after `now`, in words (`3 h 20 min`, `7 min`).
fn ahead(t: Timestamp, now: Timestamp) -> String {
    let minutes = (t.unix_micros() - now.unix_micros()) / 60_000_000;
    match (minutes / 1440, minutes % 1440 / 60, minutes % 60) {
        (0, 0, m) => format!("{m} min"),
        (0, h, m) => format!("{h} h {m} min"),
        (d, h, _) => format!("{d} d {h} h"),
    }
}

/// When a test was performed, as stated at `t` and received at `now`:
/// refused more than [`MAX_FUTURE_SECONDS`] ahead of the server's clock or
/// before 1970; within the forgiven skew, recorded as `now`. The one rule
/// for single-axis and triad submissions.
pub fn performed_when(t: Timestamp, now: Timestamp) -> Result<Timestamp, String> {
    if t > now.plus_seconds(MAX_FUTURE_SECONDS) {
        return Err(format!(
            "lies {} ahead of the server's clock ({now}); at most {} minutes of \
             clock skew are forgiven: check the station's clock",
            ahead(t, now),
            MAX_FUTURE_SECONDS / 60
        ));
    }
    if t.year() < 1970 {
        return Err("lies before 1970; check the station's clock".into());
    }
    Ok(t.min(now))
}

/// Which optional fields a submission gave: where a core refusal points.
#[derive(Debug, Clone, Copy)]
pub struct Hints {
    model_given: bool,
    batches_given: bool,
    /// Axes (i, p, o) whose gravity component is 0 at every position.
    still: [bool; 3],
}

/// The axes (i, p, o) whose gravity component is 0 at every position.
fn still_axes(positions: &[PositionIn]) -> [bool; 3] {
    let zero = |f: fn(&PositionIn) -> f64| positions.iter().all(|p| f(p) == 0.0);
    [zero(|p| p.a.i), zero(|p| p.a.p), zero(|p| p.a.o)]
}

impl Hints {
    /// The pointer of the field a core refusal concerns.
    pub fn pointer_of(&self, e: &CoreError) -> String {
        let root = Loc::Root;
        let runs = root.key("runs");
        match e {
            CoreError::RankDeficient { .. } if self.model_given => root.key("model").to_string(),
            CoreError::RankDeficient { .. } | CoreError::NoPositions => {
                root.key("positions").to_string()
            }
            CoreError::NonFiniteGravity { position, .. } => {
                root.key("positions").index(*position).to_string()
            }
            CoreError::Fusion {
                source: FusionError::TooFewRuns { .. },
                ..
            } if self.batches_given => root.key("batches").to_string(),
            CoreError::ReadingCount { run, .. } => runs.index(*run).key("readings").to_string(),
            CoreError::CopiedRun { run, .. } => runs.index(*run).to_string(),
            CoreError::NoSamples { run, position }
            | CoreError::InvalidSummary { run, position, .. } => runs
                .index(*run)
                .key("readings")
                .index(*position)
                .to_string(),
            CoreError::NonFiniteSample {
                run,
                position,
                sample,
            } => runs
                .index(*run)
                .key("readings")
                .index(*position)
                .index(*sample)
                .to_string(),
            _ => runs.to_string(),
        }
    }

    /// What to say about a core refusal: the refusal and what to do.
    pub fn detail_of(&self, e: &CoreError) -> String {
        match e {
            CoreError::RankDeficient {
                terms,
                columns,
                rank,
                ..
            } => {
                let names: Vec<&str> = terms.iter().map(|t| t.name()).collect();
                let surplus = columns.saturating_sub(*rank).max(1);
                // A term in an axis no position tilts is never seen.
                let why = [
                    ('i', "a_i", "the input axis"),
                    ('p', "a_p", "the pendulous axis (as a gate mount does)"),
                    ('o', "a_o", "the output axis (as a pendulum mount does)"),
                ]
                .iter()
                .zip(self.still)
                .find(|((axis, ..), still)| *still && names.iter().any(|n| n[1..].contains(*axis)))
                .map_or(String::new(), |((_, comp, axis), _)| {
                    format!(
                        "; {comp} = 0 at every position — the tumble never tilts {axis} — so \
                         no term in {comp} can be seen"
                    )
                });
                let drop = if surplus >= names.len() {
                    names.join(" and ")
                } else {
                    format!("{surplus} of {}", names.join(", "))
                };
                format!(
                    "{e}{why}: drop {drop} from the model (it has {surplus} term{} more than the \
                     tumble can separate) or add positions that excite them",
                    if surplus == 1 { "" } else { "s" }
                )
            }
            // Only with two runs or more (one run is not fused), so at
            // least one batch is always possible.
            CoreError::Fusion {
                source: FusionError::TooFewRuns { batches, total, .. },
                ..
            } => format!(
                "{e}: submit at least {} runs, or ask for at most {} batch{}",
                2 * batches,
                total / 2,
                if total / 2 == 1 { "" } else { "es" }
            ),
            CoreError::Fusion { .. } => {
                format!("{e}; batch estimation needs runs whose coefficients differ")
            }
            other => other.to_string(),
        }
    }
}

/// Largest |angle| (degrees) of a tumble that looks like radians: 2π, and
/// a rounding's margin.
const RADIANS_BOUND: f64 = std::f64::consts::TAU + 1e-3;

/// Why the angles look like radians, when at least two distinct angles are
/// given and all lie within ±2π: a tumble confined to ±6.3° tilts the input
/// axis by at most 0.11 g and the pendulous axis by 0.006 g, which separates
/// nothing, so no real tumble in degrees looks like this.
pub(super) fn radians(positions: &[PositionIn]) -> Option<String> {
    let angles: Vec<f64> = positions.iter().filter_map(|p| p.angle_deg).collect();
    let distinct = angles.iter().any(|a| Some(a) != angles.first());
    if !distinct || angles.iter().any(|a| a.abs() > RADIANS_BOUND) {
        return None;
    }
    let shown: Vec<String> = angles.iter().take(6).map(|a| format!("{a}")).collect();
    let degrees: Vec<String> = angles
        .iter()
        .take(6)
        .map(|a| format!("{}", (a.to_degrees() * 1e6).round() / 1e6))
        .collect();
    Some(format!(
        "the angles ({}) all lie within ±2π, which looks like radians: `angle_deg` is in \
         degrees — send ({}), i.e. radians × 180/π",
        shown.join(", "),
        degrees.join(", ")
    ))
}

/// Resolves one position with the mount; `None` when wrong (recorded).
fn position(
    p: PositionDraft,
    mount: Mount,
    errors: &mut Errors,
    at: Loc<'_>,
) -> Option<PositionIn> {
    let a = match (p.angle_deg, p.a) {
        (None, None) => {
            errors.add(
                at,
                "needs `angle_deg` (with the mount) or `a` (gravity components in g)",
            );
            return None;
        }
        (Some(deg), None) => mount.gravity(deg),
        (None, Some(a)) => a,
        (Some(deg), Some(a)) => {
            let from_angle = mount.gravity(deg);
            let off = a
                .to_array()
                .iter()
                .zip(from_angle.to_array())
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            if off > 1e-3 {
                let name = serde_json::to_value(mount).ok();
                errors.add(
                    at.key("a"),
                    format!(
                        "disagrees with angle_deg {deg} on the {} mount, which gives {:?}",
                        name.as_ref().and_then(|v| v.as_str()).unwrap_or("given"),
                        from_angle.to_array()
                    ),
                );
                return None;
            }
            a
        }
    };
    Some(PositionIn {
        angle_deg: p.angle_deg,
        a,
        label: p.label,
    })
}

/// Checks a draft against itself and the clock, and builds the core test.
/// Every problem is reported (the first hundred listed).
pub fn check(draft: Draft, now: Timestamp) -> Result<(Submission, Hints), Invalid> {
    let Draft {
        sensor_id,
        station_id,
        performed_at,
        unit,
        model,
        mount,
        positions,
        runs,
        batches,
        notes,
        sensor_type,
        stand,
        standards,
        item_received_at,
        item_condition,
        mut errors,
        not_an_object,
    } = draft;
    if not_an_object {
        return Err(errors.into_invalid());
    }
    let root = Loc::Root;
    let stand_given = stand.given();
    let mut hints = Hints {
        model_given: model.given(),
        batches_given: batches.given(),
        still: [false; 3],
    };
    for (name, given) in [
        ("sensor_id", sensor_id.given()),
        ("positions", positions.given()),
        ("runs", runs.given()),
    ] {
        if !given {
            errors.add(root.key(name), "is required");
        }
    }
    let performed_at = match performed_at {
        Slot::Value(t) => match performed_when(t, now) {
            Ok(t) => Some(t),
            Err(why) => {
                errors.add(root.key("performed_at"), why);
                None
            }
        },
        _ => None,
    };
    // The item is received before it is calibrated, and not in the future.
    let item_received_at = match item_received_at {
        Slot::Value(t) if t > now.plus_seconds(MAX_FUTURE_SECONDS) => {
            errors.add(
                root.key("item_received_at"),
                format!("lies ahead of the server's clock ({now})"),
            );
            None
        }
        Slot::Value(t) if performed_at.is_some_and(|p| t > p) => {
            errors.add(
                root.key("item_received_at"),
                format!(
                    "is after the test was performed ({}): the item is received before it is calibrated",
                    performed_at.map_or(String::new(), |p| p.to_string())
                ),
            );
            None
        }
        Slot::Value(t) => Some(t.min(now)),
        _ => None,
    };
    let mount = match mount {
        Slot::Value(m) => Some(m),
        Slot::Absent => Some(Mount::default()),
        Slot::Invalid => None,
    };
    let positions_at = root.key("positions");
    let n_positions = match &positions {
        Slot::Value(p) => Some(p.len()),
        _ => None,
    };
    let resolved: Option<Vec<Option<PositionIn>>> = match (positions, mount) {
        (Slot::Value(ps), Some(mount)) => Some(
            ps.into_iter()
                .enumerate()
                .map(|(i, p)| {
                    p.and_then(|p| position(p, mount, &mut errors, positions_at.index(i)))
                })
                .collect(),
        ),
        _ => None,
    };
    let runs_at = root.key("runs");
    let mut temperatures: Vec<Option<f64>> = Vec::new();
    let mut position_temperatures: Vec<Option<Vec<f64>>> = Vec::new();
    let runs: Option<Vec<Run>> = match runs {
        Slot::Value(rs) => {
            let mut out = Vec::with_capacity(rs.len());
            for (j, r) in rs.into_iter().enumerate() {
                let Some(r) = r else { continue };
                temperatures.push(r.temperature_c);
                position_temperatures.push(r.position_temperatures_c.clone());
                match n_positions {
                    Some(n) if n != r.readings.len() => errors.add(
                        runs_at.index(j).key("readings"),
                        format!(
                            "must hold one reading (samples or a summary) per position: {n} positions, {} given",
                            r.readings.len()
                        ),
                    ),
                    _ => out.push(Run { readings: r.readings }),
                }
            }
            Some(out)
        }
        _ => None,
    };
    // Temperatures: every run or none.
    let temperatures_c = if temperatures.iter().all(Option::is_none) {
        None
    } else if let Some(j) = temperatures.iter().position(Option::is_none) {
        errors.add(
            runs_at.index(j).key("temperature_c"),
            "is missing: give `temperature_c` for every run or for none",
        );
        None
    } else {
        Some(temperatures.into_iter().flatten().collect())
    };
    // Standards: the stand is named, and its uncertainties come from the
    // registry, not the body.
    let standards = match standards {
        Slot::Value(named) => match named.stand {
            Some(stand) => {
                if stand_given {
                    errors.add(
                        root.key("stand"),
                        "cannot be given with `standards`: the stand's uncertainties come from \
                         the registry of standards (GET /v1/standards); give one or the other",
                    );
                }
                Some(StandardsIn {
                    stand,
                    thermometer: named.thermometer,
                    gravity: named.gravity,
                })
            }
            None => {
                errors.add(
                    root.key("standards").key("stand"),
                    "is required: the tumble stand or dividing head the test was performed on",
                );
                None
            }
        },
        _ => None,
    };
    if !errors.is_empty() {
        return Err(errors.into_invalid());
    }
    // A clean draft has every required field and every element.
    let (Slot::Value(sensor_id), Some(positions), Some(runs), Some(mount)) = (
        sensor_id,
        resolved.and_then(|p| p.into_iter().collect::<Option<Vec<_>>>()),
        runs,
        mount,
    ) else {
        return Err(Invalid::one("", "the submission is incomplete"));
    };
    let model = match model {
        Slot::Value(terms) => {
            Model::new(terms).map_err(|e| Invalid::one(root.key("model"), e.to_string()))?
        }
        _ => Model::default(),
    };
    let core_positions = positions
        .iter()
        .map(|p| Position {
            a: p.a,
            rotation: p.angle_deg.map(|angle_deg| Rotation { angle_deg, mount }),
            label: p.label.clone(),
        })
        .collect();
    if let Some(why) = radians(&positions) {
        return Err(Invalid::one(root.key("positions"), why));
    }
    hints.still = still_axes(&positions);
    let test = TumbleTest::new(model, core_positions, runs)
        .map_err(|e| Invalid::one(hints.pointer_of(&e), hints.detail_of(&e)))?;
    let value = |s: Slot<String>| match s {
        Slot::Value(v) => Some(v),
        _ => None,
    };
    let submission = Submission {
        sensor_id,
        station_id: value(station_id),
        performed_at,
        unit: value(unit).unwrap_or_else(|| "output".to_owned()),
        mount,
        positions,
        batches: match batches {
            Slot::Value(b) => b,
            _ => DEFAULT_BATCHES,
        } as usize,
        notes: value(notes),
        sensor_type: value(sensor_type),
        stand: match stand {
            Slot::Value(s) => Some(StandIn {
                id: s.id,
                angle_std_arcsec: s.angle_std_arcsec.unwrap_or(0.0),
                gravity_rel_std: s.gravity_rel_std.unwrap_or(0.0),
                angle_dof: None,
                gravity_dof: None,
            }),
            _ => None,
        },
        standards,
        standards_used: Vec::new(),
        held_by: Vec::new(),
        item_received_at,
        item_condition: match item_condition {
            Slot::Value(c) => Some(c),
            _ => None,
        },
        temperatures_c,
        position_temperatures_c: if position_temperatures.iter().any(Option::is_some) {
            position_temperatures
        } else {
            Vec::new()
        },
        test,
    };
    Ok((submission, hints))
}
