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
/// documents read it.
#[derive(Debug, Deserialize)]
pub struct ThermalDoc {
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
    /// The runs submitted.
    pub runs: usize,
    /// `T_ref`, °C.
    pub reference_c: f64,
    /// The valid range, °C.
    pub range_c: [f64; 2],
    /// Every coefficient at `T_ref`.
    pub coefficients: TermMap<f64>,
    /// Their standard uncertainties.
    pub std_errors: TermMap<f64>,
    /// The sensor type it was judged by.
    pub sensor_type: Option<String>,
    /// Its judgement.
    pub decision: Option<ThermalDecision>,
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
    /// The stored calibrations it was fitted from (none for runs sent
    /// whole).
    #[serde(default)]
    pub from_calibrations: Vec<uuid::Uuid>,
    /// The model.
    pub thermal: ThermalModel,
}

/// A stored triad's temperature model's result document, as its page and
/// documents read it.
#[derive(Debug, Deserialize)]
pub struct ThermalTriadDoc {
    /// The calibration.
    pub id: uuid::Uuid,
    /// Its triad.
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
    /// The runs submitted.
    pub runs: usize,
    /// `T_ref`, °C.
    pub reference_c: f64,
    /// The valid range, °C.
    pub range_c: [f64; 2],
    /// Its elements at `T_ref`.
    pub elements: crate::store::TriadElements,
    /// The sensor type it was judged by (none in a model stored before
    /// triad models were judged).
    #[serde(default)]
    pub sensor_type: Option<String>,
    /// Its judgement.
    #[serde(default)]
    pub decision: Option<TriadThermalDecision>,
    /// When next due, when judged (RFC 3339).
    #[serde(default)]
    pub due_at: Option<String>,
    /// What its expanded uncertainties hold fixed (95.45 % in a model
    /// stored before it was stated, as then).
    #[serde(default)]
    pub coverage: Coverage,
    /// The reference standards used.
    #[serde(default)]
    pub standards: Vec<UsedStandard>,
    /// The model.
    pub thermal: TriadThermalModel,
}
