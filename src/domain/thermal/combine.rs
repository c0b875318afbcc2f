//! A temperature model from stored calibrations (issue 45 item 1): a body
//! naming single-axis calibrations of one sensor by id, each tumbled at
//! its own temperature, instead of the runs themselves. Their stored
//! submissions make one submission — every run with its temperature, in
//! the order named — to which the model is fitted exactly as to one sent
//! whole ([`super::model`]); the body itself is what is stored, so that a
//! reprocessing reads the same calibrations again.
//!
//! What the calibrations must share, each refusal naming the calibration
//! (`/calibrations/<i>`): the sensor, the model, the unit, the mount and
//! the positions; every run must carry its temperature. The combined test
//! is performed when the last of them was; its fusion batches are the
//! fewest any of them used; the standards any of them used are all the
//! model's (a nonconformity of one holds it), and of several thermometers
//! the largest `temperature_std_c` is budgeted. A triad's model from
//! stored triads is combined alike ([`triad`]).

use serde::Deserialize;
use uuid::Uuid;

use super::super::field::{Errors, Invalid, Loc};
use super::super::limits::MAX_ID_CHARS;
use super::super::review::{Basis, State};
use super::super::standards::UsedStandard;
use super::super::submission::Submission;
use super::super::text::{Chars, check_str};

mod triad;
pub use triad::{TriadConstituent, combine_triads};

/// The most calibrations one model is fitted from.
pub const MAX_CALIBRATIONS: usize = 64;

/// A body naming stored calibrations (`POST /v1/calibrations/thermal`,
/// `POST /v1/identify/thermal`, and the triad routes beside them).
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FromCalibrations {
    /// The sensor.
    #[schema(value_type = crate::domain::schema::Identifier)]
    pub sensor_id: String,
    /// Its stored calibrations, by id (single-axis ones for
    /// `/v1/calibrations/thermal`, triads for
    /// `/v1/calibrations/thermal/triad`): two to 64, each tumbled at its
    /// own temperature.
    #[schema(schema_with = ids)]
    pub calibrations: Vec<String>,
    /// The station, if any.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_identifier)]
    pub station_id: Option<String>,
}

/// The schema of `calibrations`: two to [`MAX_CALIBRATIONS`] ids.
fn ids() -> utoipa::openapi::schema::ArrayBuilder {
    use utoipa::openapi::schema::{KnownFormat, SchemaFormat, Type};
    utoipa::openapi::schema::ArrayBuilder::new()
        .items(
            crate::domain::schema::of_type(Type::String)
                .format(Some(SchemaFormat::KnownFormat(KnownFormat::Uuid))),
        )
        .min_items(Some(2))
        .max_items(Some(MAX_CALIBRATIONS))
}

/// A stored calibration as a model reads it.
pub struct Constituent {
    /// Its id.
    pub id: Uuid,
    /// Its stored submission, read again.
    pub submission: Submission,
    /// The standards it used.
    pub standards: Vec<UsedStandard>,
}

impl FromCalibrations {
    /// Whether `json` is a body naming stored calibrations: an object
    /// with a `calibrations` member.
    pub fn named(json: &[u8]) -> bool {
        #[derive(Deserialize)]
        struct Probe {
            calibrations: Option<serde::de::IgnoredAny>,
        }
        serde_json::from_slice::<Probe>(json).is_ok_and(|p| p.calibrations.is_some())
    }

    /// The ids named, checked: identifiers, two to [`MAX_CALIBRATIONS`]
    /// distinct UUIDs.
    pub fn check(&self) -> Result<Vec<Uuid>, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        for (name, value) in [
            ("sensor_id", Some(&self.sensor_id)),
            ("station_id", self.station_id.as_ref()),
        ] {
            if let Some(v) = value
                && let Err(why) = check_str(v, MAX_ID_CHARS, Chars::Identifier)
            {
                errors.add(root.key(name), why);
            }
        }
        let at = root.key("calibrations");
        let n = self.calibrations.len();
        if !(2..=MAX_CALIBRATIONS).contains(&n) {
            errors.add(
                at,
                format!(
                    "must name 2 to {MAX_CALIBRATIONS} calibrations, each at its own \
                     temperature, not {n}"
                ),
            );
        }
        let mut ids = Vec::with_capacity(n);
        for (i, raw) in self.calibrations.iter().enumerate() {
            match Uuid::parse_str(raw) {
                Ok(id) if ids.contains(&id) => {
                    errors.add(at.index(i), format!("names calibration {id} again"));
                }
                Ok(id) => ids.push(id),
                Err(_) => errors.add(at.index(i), "must be a calibration's id (a UUID)"),
            }
        }
        errors.finish(|| ids)
    }
}

/// Why calibration `id`, in `state`, cannot make a model, if it cannot:
/// only calibrations that count (submitted or approved) do, and not one
/// held under review by a standard's nonconformity (the model would not be
/// held). The one rule of the model's request, which reads the
/// calibrations, and of the store, which checks them again in the
/// transaction that stores the model (a reviewer may act in between).
pub fn unusable(id: Uuid, state: State) -> Option<String> {
    if !state.counts(Basis::NotRejected) {
        return Some(format!(
            "calibration {id} is {}: only calibrations that count (submitted or approved) \
             make a model; name what replaced it",
            state.as_str()
        ));
    }
    (state == State::UnderReview).then(|| {
        format!(
            "calibration {id} is under review: a nonconformity of a standard it used holds \
             it, and a model fitted from it would not be held; a reviewer approves it again \
             (or withdraws it) first"
        )
    })
}

/// The submission `parts` make together for sensor `sensor_id` and
/// station `station_id` (module doc); `parts` in the order named.
pub fn combine(
    sensor_id: &str,
    station_id: Option<String>,
    parts: Vec<Constituent>,
) -> Result<Submission, Invalid> {
    let root = Loc::Root;
    let named = root.key("calibrations");
    let at = |i: usize| named.index(i).to_string();
    let Some(first) = parts.first() else {
        return Err(Invalid::one(
            Loc::Root.key("calibrations"),
            "names no calibration",
        ));
    };
    let base = &first.submission;
    let mut errors = Errors::default();
    let mut runs = Vec::new();
    let mut temperatures = Vec::new();
    let mut per_position: Vec<Option<Vec<f64>>> = Vec::new();
    for (i, p) in parts.iter().enumerate() {
        let s = &p.submission;
        let id = p.id;
        let differs = |what: &str, this: String, first: String| {
            format!(
                "calibration {id}'s {what} ({this}) is not the first's ({first}): a model is \
                 fitted to calibrations of one test setup"
            )
        };
        if s.unit != base.unit {
            errors.add(at(i), differs("unit", s.unit.clone(), base.unit.clone()));
        } else if s.test.model() != base.test.model() {
            errors.add(
                at(i),
                differs("model", terms(s.test.model()), terms(base.test.model())),
            );
        } else if s.mount != base.mount || s.test.positions() != base.test.positions() {
            errors.add(
                at(i),
                format!(
                    "calibration {id}'s positions or mount are not the first's: a model is \
                     fitted to calibrations of one tumble sequence"
                ),
            );
        }
        match &s.temperatures_c {
            Some(t) => temperatures.extend_from_slice(t),
            None => errors.add(
                at(i),
                format!(
                    "calibration {id}'s runs carry no temperature_c: a model needs every run's"
                ),
            ),
        }
        runs.extend_from_slice(s.test.runs());
        if s.position_temperatures_c.is_empty() {
            per_position.extend(s.test.runs().iter().map(|_| None));
        } else {
            per_position.extend_from_slice(&s.position_temperatures_c);
        }
    }
    errors.finish(|| ())?;
    let test = accelcal_core::TumbleTest::new(
        base.test.model().clone(),
        base.test.positions().to_vec(),
        runs,
    )
    .map_err(|e| {
        Invalid::one(
            Loc::Root.key("calibrations"),
            format!("their runs do not make one test: {e}"),
        )
    })?;
    Ok(Submission {
        sensor_id: sensor_id.to_owned(),
        station_id,
        performed_at: parts.iter().filter_map(|p| p.submission.performed_at).max(),
        unit: base.unit.clone(),
        mount: base.mount,
        positions: base.positions.clone(),
        batches: parts
            .iter()
            .map(|p| p.submission.batches)
            .min()
            .unwrap_or(1),
        notes: None,
        sensor_type: None,
        stand: None,
        standards: None,
        item_received_at: None,
        item_condition: None,
        standards_used: union(parts.iter().map(|p| p.standards.as_slice())),
        held_by: Vec::new(),
        temperatures_c: Some(temperatures),
        position_temperatures_c: if per_position.iter().any(Option::is_some) {
            per_position
        } else {
            Vec::new()
        },
        test,
    })
}

/// The standards of `each` calibration, each (role, standard,
/// certificate) once, in the order first used.
pub(super) fn union<'a>(each: impl Iterator<Item = &'a [UsedStandard]>) -> Vec<UsedStandard> {
    let mut standards: Vec<UsedStandard> = Vec::new();
    for u in each.flatten() {
        let known = standards.iter().any(|k| {
            (&k.role, &k.standard_id, &k.certificate.number)
                == (&u.role, &u.standard_id, &u.certificate.number)
        });
        if !known {
            standards.push(u.clone());
        }
    }
    standards
}

/// A model's terms, as a body lists them (`k0, ki, kp`).
fn terms(m: &accelcal_core::Model) -> String {
    let names: Vec<&str> = m.terms().iter().map(|t| t.name()).collect();
    names.join(", ")
}
