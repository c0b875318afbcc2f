//! A triad's temperature model from stored triad calibrations (issue 45
//! item 1): the body naming them ([`super::FromCalibrations`]) is read as
//! a single axis's is, and their stored submissions make one triad
//! submission, to which the model is fitted exactly as to one sent whole
//! ([`super::super::triad_model`]).
//!
//! What the calibrations must share, each refusal naming the calibration
//! (`/calibrations/<i>`): the unit and the method. Of known orientations,
//! the positions (each calibration's runs are appended, with their
//! temperatures — given per position too — and the fusion's batches are
//! the fewest any of them used); none with second-order terms, which a
//! model does not carry over temperature. From the gravity magnitude,
//! static positions and recordings may be mixed: a recording's static
//! intervals are found as its calibration found them, each a position at
//! its samples' mean temperature, and every calibration's positions are
//! appended. Every calibration must have been given its temperatures
//! (a triad at one temperature carries them: [`crate::domain::triad`]).
//! The stand is the first's; standards are gathered as a single axis's
//! ([`super::union`]).

use accelcal_core::coverage::Coverage;
use accelcal_core::thermal::TOLERANCE_K;
use uuid::Uuid;

use super::super::super::field::{Errors, Invalid, Loc};
use super::super::super::standards::UsedStandard;
use super::super::super::timestamp::Timestamp;
use super::super::super::triad::{Form, TriadSubmission};
use super::super::triad::intervals;

/// A stored triad calibration as a model reads it.
pub struct TriadConstituent {
    /// Its id.
    pub id: Uuid,
    /// When it was performed, as stored.
    pub performed_at: Timestamp,
    /// Its stored submission, read again.
    pub submission: TriadSubmission,
    /// The standards it used.
    pub standards: Vec<UsedStandard>,
}

/// What the calibrations' forms make together.
enum Joined {
    Known {
        positions: Vec<[f64; 3]>,
        runs: Vec<accelcal_core::triad::TriadRun>,
        batches: usize,
        temperatures_c: Vec<f64>,
        position_temperatures_c: Vec<Option<Vec<f64>>>,
    },
    Static {
        means: Vec<[f64; 3]>,
        temperatures_c: Vec<f64>,
    },
}

/// The triad submission `parts` make together for sensor `sensor_id` and
/// station `station_id` (module doc), with the standards they used;
/// `parts` in the order named.
pub fn combine_triads(
    sensor_id: &str,
    station_id: Option<String>,
    parts: Vec<TriadConstituent>,
) -> Result<(TriadSubmission, Vec<UsedStandard>), Invalid> {
    let named = Loc::Root.key("calibrations");
    let at = |i: usize| named.index(i).to_string();
    let Some(first) = parts.first() else {
        return Err(Invalid::one(named, "names no calibration"));
    };
    let (unit, stand) = (first.submission.unit.clone(), first.submission.stand);
    let mut errors = Errors::default();
    let mut joined: Option<Joined> = None;
    for (i, p) in parts.iter().enumerate() {
        let id = p.id;
        if p.submission.unit != unit {
            errors.add(
                at(i),
                format!(
                    "calibration {id}'s unit ({}) is not the first's ({unit}): a model is fitted \
                     to calibrations of one test setup",
                    p.submission.unit
                ),
            );
            continue;
        }
        if let Err(why) = join(&mut joined, &p.submission.form) {
            errors.add(at(i), format!("calibration {id} {why}"));
        }
    }
    errors.finish(|| ())?;
    let form = match joined {
        Some(Joined::Known {
            positions,
            runs,
            batches,
            temperatures_c,
            position_temperatures_c,
        }) => Form::Known {
            positions,
            runs,
            batches,
            second_order: false,
            temperatures_c: Some(temperatures_c),
            position_temperatures_c: if position_temperatures_c.iter().any(Option::is_some) {
                position_temperatures_c
            } else {
                Vec::new()
            },
        },
        Some(Joined::Static {
            means,
            temperatures_c,
        }) => Form::Unknown {
            means,
            temperatures_c: Some(temperatures_c),
        },
        None => return Err(Invalid::one(named, "names no calibration")),
    };
    let standards = super::union(parts.iter().map(|p| p.standards.as_slice()));
    let sub = TriadSubmission {
        sensor_id: Some(sensor_id.to_owned()),
        station_id,
        performed_at: parts.iter().map(|p| p.performed_at).max(),
        unit,
        form,
        stand,
        sensor_type: None,
        coverage: Coverage::default(),
        standards: Vec::new(),
    };
    Ok((sub, standards))
}

/// `form` appended to what the calibrations before it made, or why not
/// (completing "calibration <id> …").
fn join(joined: &mut Option<Joined>, form: &Form) -> Result<(), String> {
    const UNTEMPERED: &str = "carries no temperatures: a model needs each calibration's (give \
                              the runs', positions' or samples' temperature_c when it is stored)";
    match (form, joined) {
        (Form::Known { second_order, .. }, _) if *second_order => {
            Err("models second-order terms, which a temperature model does not carry".into())
        }
        (
            Form::Known {
                temperatures_c: None,
                ..
            }
            | Form::Unknown {
                temperatures_c: None,
                ..
            }
            | Form::Recording {
                temperatures_c: None,
                ..
            },
            _,
        ) => Err(UNTEMPERED.into()),
        (
            Form::Known {
                positions,
                runs,
                batches,
                temperatures_c: Some(t),
                position_temperatures_c,
                ..
            },
            joined,
        ) => {
            let per_run = |k: usize| -> Vec<Option<Vec<f64>>> {
                if position_temperatures_c.is_empty() {
                    vec![None; k]
                } else {
                    position_temperatures_c.clone()
                }
            };
            match joined {
                None => {
                    *joined = Some(Joined::Known {
                        positions: positions.clone(),
                        runs: runs.clone(),
                        batches: *batches,
                        temperatures_c: t.clone(),
                        position_temperatures_c: per_run(runs.len()),
                    });
                    Ok(())
                }
                Some(Joined::Known {
                    positions: first,
                    runs: all,
                    batches: fewest,
                    temperatures_c,
                    position_temperatures_c: all_per_run,
                }) => {
                    if positions != first {
                        return Err("was tumbled through other orientations than the first: a \
                                    model is fitted to calibrations of one tumble sequence"
                            .into());
                    }
                    all.extend_from_slice(runs);
                    *fewest = (*fewest).min(*batches);
                    temperatures_c.extend_from_slice(t);
                    all_per_run.extend(per_run(runs.len()));
                    Ok(())
                }
                Some(Joined::Static { .. }) => Err(mixed()),
            }
        }
        (Form::Unknown { .. } | Form::Recording { .. }, Some(Joined::Known { .. })) => Err(mixed()),
        (form, joined) => {
            let (means, t) = match form {
                Form::Unknown {
                    means,
                    temperatures_c: Some(t),
                } => (means.clone(), t.clone()),
                Form::Recording {
                    rate_hz,
                    samples,
                    detector,
                    temperatures_c: Some(t),
                } => intervals(*rate_hz, samples, detector, t, TOLERANCE_K)
                    .map_err(|e| format!("does not read again: {e}"))?,
                _ => return Err(UNTEMPERED.into()),
            };
            match joined {
                Some(Joined::Static {
                    means: all,
                    temperatures_c,
                }) => {
                    all.extend(means);
                    temperatures_c.extend(t);
                }
                _ => {
                    *joined = Some(Joined::Static {
                        means,
                        temperatures_c: t,
                    });
                }
            }
            Ok(())
        }
    }
}

/// Why known orientations and the gravity magnitude do not mix.
fn mixed() -> String {
    "is not of the first's method (known orientations, or static positions and recordings \
     fitted from the gravity magnitude): a model is fitted to calibrations of one method"
        .into()
}
