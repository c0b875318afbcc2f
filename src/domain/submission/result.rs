//! The calibration result as it goes on the wire and into storage.

use accelcal_core::{Calibration, Gravity, Model, Mount};
use serde::Serialize;
use uuid::Uuid;

use crate::domain::standards::UsedStandard;

use super::{Evaluated, PositionIn, StandIn};
use crate::domain::metrology::Metrology;
use crate::domain::timestamp::Timestamp;

/// A resolved position in a result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PositionOut {
    /// Gravity components `[a_i, a_p, a_o]` in g.
    pub a: Gravity,
    /// The dividing-head angle, when the position was given by one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<f64>,
    /// The label, when given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
}

impl From<&PositionIn> for PositionOut {
    fn from(p: &PositionIn) -> Self {
        PositionOut {
            a: p.a,
            angle_deg: p.angle_deg,
            label: p.label.clone(),
        }
    }
}

/// The versions of the method that computed a result: accelcal's (what it
/// reads, checks and stores) and its core's (every number).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Method {
    /// accelcal's version.
    pub accelcal: &'static str,
    /// accelcal-core's version ([`accelcal_core::VERSION`]).
    pub core: &'static str,
}

impl Method {
    /// This build's.
    pub const CURRENT: Method = Method {
        accelcal: env!("CARGO_PKG_VERSION"),
        core: accelcal_core::VERSION,
    };
}

/// A calibration result: the submission's metadata and the core's numbers.
/// `id` is absent for `/v1/identify`, which stores nothing.
#[derive(Debug, Serialize)]
pub struct ResultView<'a> {
    /// The method that computed it.
    pub method: Method,
    /// Time-ordered identifier (UUIDv7).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub id: Option<Uuid>,
    /// The sensor.
    pub sensor_id: &'a str,
    /// The station that submitted it, if known.
    pub station_id: Option<&'a str>,
    /// When the test was performed (defaults to `received_at`).
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// Unit of the outputs and of every coefficient.
    pub unit: &'a str,
    /// The model's terms.
    pub model: &'a Model,
    /// The mount used to resolve angles.
    pub mount: Mount,
    /// Number of fusion batches.
    pub batches: usize,
    /// Free text from the submission.
    pub notes: Option<&'a str>,
    /// The positions, resolved to gravity components.
    pub positions: Vec<PositionOut>,
    /// The sensor type in force (named in the body, or the sensor's), if any.
    pub sensor_type: Option<&'a str>,
    /// The tumble stand, when the body described it or named it among its
    /// standards (then as the registry describes it).
    pub stand: Option<&'a StandIn>,
    /// The reference standards the body named, as used: each with the
    /// certificate it was in calibration by when the test was performed.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub standards: &'a [UsedStandard],
    /// The nonconformities of those standards it was performed inside the
    /// windows of: it is stored under review, its coefficients not usable
    /// until a reviewer records a disposition.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub held_by: &'a [crate::domain::nonconformity::HeldBy],
    /// When the laboratory received the item, when the body said.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub item_received_at: Option<Timestamp>,
    /// The item's condition on receipt, when the body said.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub item_condition: Option<&'a str>,
    /// The runs' temperatures (°C), when they were given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperatures_c: Option<&'a [f64]>,
    /// The calibration this one supersedes, and why (a correction).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub supersedes: Option<crate::domain::review::Supersedes>,
    /// Condition number, runs, mean, fused, normalized.
    #[serde(flatten)]
    pub calibration: &'a Calibration,
    /// Uncertainty, decision, as found, due date, temperature, quality.
    #[serde(flatten)]
    pub metrology: &'a Metrology,
}

impl<'a> ResultView<'a> {
    /// The view of an evaluated submission.
    pub fn new(
        e: &'a Evaluated,
        id: Option<Uuid>,
        station_id: Option<&'a str>,
        received_at: Timestamp,
        sensor_type: Option<&'a str>,
        metrology: &'a Metrology,
    ) -> Self {
        let s = &e.submission;
        ResultView {
            method: Method::CURRENT,
            id,
            sensor_id: &s.sensor_id,
            station_id,
            performed_at: s.performed_at.unwrap_or(received_at),
            received_at,
            unit: &s.unit,
            model: s.test.model(),
            mount: s.mount,
            batches: s.batches,
            notes: s.notes.as_deref(),
            positions: s.positions.iter().map(PositionOut::from).collect(),
            sensor_type,
            stand: s.stand.as_ref(),
            standards: &s.standards_used,
            held_by: &s.held_by,
            item_received_at: s.item_received_at,
            item_condition: s.item_condition.as_deref(),
            temperatures_c: s.temperatures_c.as_deref(),
            supersedes: None,
            calibration: &e.calibration,
            metrology,
        }
    }
}
