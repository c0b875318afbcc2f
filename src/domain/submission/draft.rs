//! A submission as read from JSON or CSV, before the checks that relate its
//! fields to each other: every field that was given and well-typed, and a
//! record of every problem found so far.

use accelcal_core::{Gravity, Mount, Reading, Term};

use crate::domain::field::Errors;
use crate::domain::timestamp::Timestamp;

/// One field of a draft.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Slot<T> {
    /// Not given (or `null`).
    #[default]
    Absent,
    /// Given, but wrong: the problem is already recorded.
    Invalid,
    /// Given and well-typed.
    Value(T),
}

impl<T> Slot<T> {
    /// The slot of a value read with a possible problem (already recorded).
    pub fn from_read(value: Option<T>) -> Self {
        value.map_or(Slot::Invalid, Slot::Value)
    }

    /// Whether the field was given at all.
    pub fn given(&self) -> bool {
        !matches!(self, Slot::Absent)
    }
}

/// A position as given: by angle, by gravity components, or both.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PositionDraft {
    /// The dividing-head angle in degrees.
    pub angle_deg: Option<f64>,
    /// Explicit gravity components `[a_i, a_p, a_o]`, their norm checked.
    pub a: Option<Gravity>,
    /// The label.
    pub label: Option<String>,
}

/// A run as given: a reading per position (each within the limits).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunDraft {
    /// `readings[i]`: the samples at position `i`, or their summary.
    pub readings: Vec<Reading>,
    /// The temperature the run was made at, °C (the mean of its
    /// positions' when given per position).
    pub temperature_c: Option<f64>,
    /// Its temperature at each position, °C, when given so (a chamber
    /// that drifts during a run).
    pub position_temperatures_c: Option<Vec<f64>>,
}

/// The tumble stand as given.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StandDraft {
    /// Its id.
    pub id: Option<String>,
    /// Indexing error (1σ), arcseconds.
    pub angle_std_arcsec: Option<f64>,
    /// Relative uncertainty of gravity.
    pub gravity_rel_std: Option<f64>,
}

/// The standards named, as given.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StandardsDraft {
    /// The stand's id.
    pub stand: Option<String>,
    /// The thermometer's id.
    pub thermometer: Option<String>,
    /// The gravity value's id.
    pub gravity: Option<String>,
}

/// Everything read from a submission body.
#[derive(Debug, Default)]
pub struct Draft {
    /// `sensor_id`.
    pub sensor_id: Slot<String>,
    /// `station_id`.
    pub station_id: Slot<String>,
    /// `performed_at`, parsed (its range is checked against the clock later).
    pub performed_at: Slot<Timestamp>,
    /// `unit`.
    pub unit: Slot<String>,
    /// `model`, distinct known terms.
    pub model: Slot<Vec<Term>>,
    /// `mount`.
    pub mount: Slot<Mount>,
    /// `positions`; an element that was wrong is `None`.
    pub positions: Slot<Vec<Option<PositionDraft>>>,
    /// `runs`; a run that was wrong is `None`.
    pub runs: Slot<Vec<Option<RunDraft>>>,
    /// `batches`.
    pub batches: Slot<u64>,
    /// `notes`.
    pub notes: Slot<String>,
    /// `sensor_type`.
    pub sensor_type: Slot<String>,
    /// `stand`.
    pub stand: Slot<StandDraft>,
    /// `standards`.
    pub standards: Slot<StandardsDraft>,
    /// `item_received_at`, parsed.
    pub item_received_at: Slot<Timestamp>,
    /// `item_condition`.
    pub item_condition: Slot<String>,
    /// Problems found while reading.
    pub errors: Errors,
    /// The body was not an object at all (nothing else is worth saying).
    pub not_an_object: bool,
}
