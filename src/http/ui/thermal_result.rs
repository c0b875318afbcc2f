//! A stored temperature model's result document as the pages and
//! documents read it (the `StoredThermal` and `StoredThermalTriad` the
//! service wrote, issue 45):
//! read apart from the kind's rendering so that reading a stored result
//! depends on no renderer.

use accelcal_core::TermMap;
use accelcal_core::coverage::Coverage;
use serde::Deserialize;

use crate::domain::review::Supersedes;
use crate::domain::standards::UsedStandard;
use crate::domain::thermal::decision::{ThermalDecision, TriadThermalDecision};
use crate::domain::thermal::{ThermalModel, TriadThermalModel};

/// A stored temperature model's result document, as its page and
/// documents read it: what a single axis's and a triad's share, their
/// model `M`, its decision `D`, and what only the kind states, `X`.
#[derive(Debug, Deserialize)]
pub struct ModelDoc<M, D, X> {
    /// The calibration.
    pub id: uuid::Uuid,
    /// Its sensor.
    pub sensor_id: String,
    /// The station.
    pub station_id: Option<String>,
    /// When performed (RFC 3339).
    pub performed_at: String,
    /// When received (RFC 3339).
    pub received_at: String,
    /// The calibration it supersedes.
    pub supersedes: Option<Supersedes>,
    /// The outputs' unit.
    pub unit: String,
    /// The runs submitted (a triad's static positions).
    pub runs: usize,
    /// `T_ref`, °C.
    pub reference_c: f64,
    /// The valid range, °C.
    pub range_c: [f64; 2],
    /// The sensor type it was judged by (none in a triad's model stored
    /// before those were judged).
    #[serde(default)]
    pub sensor_type: Option<String>,
    /// Its judgement.
    #[serde(default = "Option::default")]
    pub decision: Option<D>,
    /// When next due, when judged (RFC 3339).
    #[serde(default)]
    pub due_at: Option<String>,
    /// What its expanded uncertainties hold fixed (95.45 % in a model
    /// stored before it was stated, as then).
    #[serde(default)]
    pub coverage: Coverage,
    /// The reference standards used (none in a model stored before they
    /// were resolved).
    #[serde(default)]
    pub standards: Vec<UsedStandard>,
    /// The model.
    pub thermal: M,
    /// The stored calibrations it was fitted from (none for runs sent
    /// whole).
    #[serde(default)]
    pub from_calibrations: Vec<uuid::Uuid>,
    /// What only this kind states.
    #[serde(flatten)]
    pub kind: X,
}

/// What only a single axis's model states.
#[derive(Debug, Deserialize)]
pub struct SingleAxis {
    /// Every coefficient at `T_ref`.
    pub coefficients: TermMap<f64>,
    /// Their standard uncertainties.
    pub std_errors: TermMap<f64>,
}

/// What only a triad's model states.
#[derive(Debug, Deserialize)]
pub struct Triad {
    /// Its elements at `T_ref`.
    pub elements: crate::store::TriadElements,
}

/// A single axis's stored temperature model.
pub type ThermalDoc = ModelDoc<ThermalModel, ThermalDecision, SingleAxis>;

/// A triad's stored temperature model.
pub type ThermalTriadDoc = ModelDoc<TriadThermalModel, TriadThermalDecision, Triad>;
