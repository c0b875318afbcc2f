//! Tumble-test submissions: a body (JSON or CSV) read into a [`Draft`],
//! checked field by field into a [`Submission`] holding the core's
//! [`TumbleTest`], and calibrated.
//!
//! This is the one place where the wire format meets the core ("parse, don't
//! validate"): [`evaluate`] either returns a calibrated [`Evaluated`] or every
//! problem it found (the first hundred listed), each with the JSON pointer of
//! the offending value.

mod check;
pub mod csv;
mod draft;
pub mod json;
mod node;
mod result;

pub use check::{check, performed_when};
pub use draft::{Draft, PositionDraft, RunDraft, Slot, StandDraft};
pub use result::{Method, PositionOut, ResultView};

use accelcal_core::{Calibration, Gravity, Mount, TumbleTest};

use super::field::Invalid;
use super::timestamp::Timestamp;

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
    "sensor_type",
    "stand",
    "standards",
    "item_received_at",
    "item_condition",
];

/// The media types a submission may come in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Media {
    /// `application/json`.
    Json,
    /// `text/csv`.
    Csv,
}

/// Why a body could not be read at all (answered 400, not 422).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Unreadable {
    /// Not JSON.
    #[error("the body is not valid JSON: {0}")]
    Json(String),
    /// Not UTF-8.
    #[error("the CSV body is not UTF-8: {0}")]
    Utf8(String),
}

/// Why a submission was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refused {
    /// The body could not be read (400).
    #[error(transparent)]
    Unreadable(#[from] Unreadable),
    /// The body was read, and is wrong or cannot be calibrated (422).
    #[error("{0}")]
    Invalid(#[from] Invalid),
}

/// Reads a body of either media type.
pub fn read(media: Media, bytes: &[u8]) -> Result<Draft, Unreadable> {
    match media {
        Media::Json => json::read(bytes).map_err(Unreadable::Json),
        Media::Csv => csv::read(bytes).map_err(|e| Unreadable::Utf8(e.to_string())),
    }
}

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
    /// The sensor type named in the body, if any.
    pub sensor_type: Option<String>,
    /// The tumble stand, if the body describes it (or, once the standards
    /// the body names are resolved, as the registry describes it).
    pub stand: Option<StandIn>,
    /// The reference standards the body names, by id.
    pub standards: Option<StandardsIn>,
    /// When the laboratory received the item (the sensor), if given.
    pub item_received_at: Option<Timestamp>,
    /// The item's condition on receipt, if given.
    pub item_condition: Option<String>,
    /// Those standards as the registry describes them, once resolved
    /// (empty until then, and for a body that names none).
    pub standards_used: Vec<crate::domain::standards::UsedStandard>,
    /// The nonconformities of those standards that hold the test (performed
    /// in their windows), once resolved: it is stored under review.
    pub held_by: Vec<crate::domain::nonconformity::HeldBy>,
    /// Each run's temperature (°C), when the runs give them (all or none):
    /// the mean of its positions' when given per position.
    pub temperatures_c: Option<Vec<f64>>,
    /// Each run's temperature at every position, when some run gives them
    /// so (`None` for a run that gives one); empty otherwise.
    pub position_temperatures_c: Vec<Option<Vec<f64>>>,
    /// The tumble test handed to the core.
    pub test: TumbleTest,
}

/// The tumble stand of a submission: its systematic uncertainties (1σ).
#[derive(Clone, Debug, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct StandIn {
    /// The stand's id, if given.
    pub id: Option<String>,
    /// Indexing (angle) error of the dividing head, arcseconds (default 0).
    pub angle_std_arcsec: f64,
    /// Relative uncertainty of the local gravity magnitude (default 0).
    pub gravity_rel_std: f64,
    /// The indexing error's degrees of freedom, when the stand's certificate
    /// states them (otherwise infinite: a Type B evaluation).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_dof: Option<f64>,
    /// The gravity value's degrees of freedom, when its certificate states
    /// them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity_dof: Option<f64>,
}

impl StandIn {
    /// The stand as the core's budget takes it.
    pub fn core(&self) -> accelcal_core::uncertainty::Stand {
        accelcal_core::uncertainty::Stand {
            angle_std_rad: self.angle_std_arcsec * accelcal_core::uncertainty::ARCSEC,
            gravity_rel_std: self.gravity_rel_std,
            angle_dof: self.angle_dof,
            gravity_dof: self.gravity_dof,
        }
    }
}

/// The reference standards a submission names (`standards`), by id: the
/// tumble stand, and optionally a thermometer and a local gravity value.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StandardsIn {
    /// The tumble stand or dividing head.
    pub stand: String,
    /// The thermometer the run temperatures were read with.
    pub thermometer: Option<String>,
    /// The local gravity value.
    pub gravity: Option<String>,
}

/// A submission with its calibration.
#[derive(Clone, Debug)]
pub struct Evaluated {
    /// The checked submission.
    pub submission: Submission,
    /// Per-run and fused results.
    pub calibration: Calibration,
}

/// Reads, checks, identifies and fuses a submission body.
pub fn evaluate(media: Media, bytes: &[u8], now: Timestamp) -> Result<Evaluated, Refused> {
    let draft = read(media, bytes)?;
    let (submission, hints) = check(draft, now)?;
    let calibration = submission
        .test
        .calibrate(submission.batches)
        .map_err(|e| Invalid::one(hints.pointer_of(&e), hints.detail_of(&e)))?;
    Ok(Evaluated {
        submission,
        calibration,
    })
}

#[cfg(test)]
mod tests;
