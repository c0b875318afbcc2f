//! What the store reads and writes: plain, typed records.

use accelcal_core::decision::Verdict;
use accelcal_core::{Model, TermMap};
use bytes::Bytes;
use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::StoreError;
use crate::domain::status::Status;
use crate::domain::timestamp::Timestamp;

/// Everything stored for one calibration, written in one transaction.
#[derive(Debug, Clone)]
pub struct NewCalibration {
    /// UUIDv7.
    pub id: Uuid,
    /// The sensor.
    pub sensor_id: String,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// Output unit.
    pub unit: String,
    /// The model's terms.
    pub model: Model,
    /// Number of runs.
    pub runs: usize,
    /// Fused coefficients.
    pub coefficients: TermMap<f64>,
    /// Fused standard errors.
    pub std_errors: TermMap<f64>,
    /// The whole result document (what `GET /v1/calibrations/{id}` returns).
    pub result: Bytes,
    /// The submitted body (decompressed), byte for byte.
    pub submission: Bytes,
    /// The submitted body's media type.
    pub content_type: String,
    /// The principal that submitted it.
    pub submitted_by: String,
    /// The sensor type in force, if any.
    pub sensor_type: Option<String>,
    /// Whether the submission named that type (it then becomes the sensor's).
    pub assigns_type: bool,
    /// The decision's verdict (typed sensors).
    pub verdict: Option<Verdict>,
    /// When the sensor is due again (typed sensors).
    pub due_at: Option<Timestamp>,
    /// The expanded uncertainty of every fused coefficient (none only for
    /// calibrations stored before uncertainty budgets, when copied).
    pub expanded: Option<TermMap<f64>>,
}

impl NewCalibration {
    /// Refuses a record whose fused coefficients or standard errors hold a
    /// non-finite number: whatever reaches the store, nothing NaN or infinite
    /// is ever written (every engine calls this, and the schema checks again).
    pub fn check(&self) -> Result<(), StoreError> {
        let none = TermMap(Vec::new());
        for (what, map) in [
            ("coefficient", &self.coefficients),
            ("standard error", &self.std_errors),
            (
                "expanded uncertainty",
                self.expanded.as_ref().unwrap_or(&none),
            ),
        ] {
            if let Some((term, v)) = map.iter().find(|(_, v)| !v.is_finite()) {
                return Err(StoreError::Refused(format!(
                    "the fused {what} of `{term}` is {v}"
                )));
            }
        }
        Ok(())
    }
}

/// A submitted body as stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredSubmission {
    /// Media type it was sent with.
    pub content_type: String,
    /// The bytes.
    pub body: Bytes,
}

/// A calibration without its per-run detail: what lists and control systems need.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct CalibrationSummary {
    /// Calibration id.
    pub id: Uuid,
    /// The sensor.
    pub sensor_id: String,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// Unit of the outputs and of every coefficient.
    pub unit: String,
    /// Model terms.
    #[schema(value_type = crate::domain::schema::ModelSchema)]
    pub model: Model,
    /// Number of runs.
    #[schema(minimum = 1)]
    pub runs: usize,
    /// Fused coefficients.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    pub coefficients: TermMap<f64>,
    /// Fused standard errors.
    #[schema(value_type = crate::domain::schema::CoefficientMap)]
    pub std_errors: TermMap<f64>,
    /// The sensor type in force at the calibration, if any.
    pub sensor_type: Option<String>,
    /// Its verdict against that type's limits, if typed.
    #[schema(value_type = Option<crate::domain::schema::VerdictSchema>)]
    pub verdict: Option<Verdict>,
    /// When the sensor was next due, if typed.
    pub due_at: Option<Timestamp>,
    /// The expanded uncertainty of every fused coefficient (null for
    /// calibrations stored before uncertainty budgets).
    #[schema(value_type = Option<crate::domain::schema::CoefficientMap>)]
    pub expanded: Option<TermMap<f64>>,
}

#[cfg(test)]
impl CalibrationSummary {
    /// A minimal summary for tests: sensor `sensor`, model `k0 + ki`, one
    /// run, performed and received at 2026-01-01, standard errors zero.
    pub(crate) fn for_test(id: u128, sensor: &str, k0: f64, ki: f64) -> Self {
        use accelcal_core::Term;
        let at = Timestamp::parse("2026-01-01T00:00:00Z").expect("a valid timestamp");
        Self {
            id: Uuid::from_u128(id),
            sensor_id: sensor.into(),
            station_id: None,
            performed_at: at,
            received_at: at,
            unit: "mA".into(),
            model: Model::new(vec![Term::K0, Term::Ki]).expect("a valid model"),
            runs: 1,
            coefficients: TermMap(vec![(Term::K0, k0), (Term::Ki, ki)]),
            std_errors: TermMap(vec![(Term::K0, 0.0), (Term::Ki, 0.0)]),
            sensor_type: None,
            verdict: None,
            due_at: None,
            expanded: None,
        }
    }
}

/// A sensor with its calibration count and latest calibration.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct SensorSummary {
    /// The sensor.
    pub sensor_id: String,
    /// Number of stored calibrations.
    #[schema(minimum = 1)]
    pub calibration_count: u64,
    /// Earliest `performed_at`.
    pub first_performed_at: Timestamp,
    /// Latest `performed_at`.
    pub latest_performed_at: Timestamp,
    /// The sensor type assigned to it, if any.
    pub sensor_type: Option<String>,
    /// The latest calibration's verdict, if it was typed.
    #[schema(value_type = Option<crate::domain::schema::VerdictSchema>)]
    pub latest_verdict: Option<Verdict>,
    /// When the sensor is due, from its latest calibration.
    pub due_at: Option<Timestamp>,
    /// Its status now: failed, overdue, due_soon, ok or unknown.
    pub status: Status,
    /// The calibration with the latest `performed_at` (ties: the later id).
    pub latest: CalibrationSummary,
}

/// Which sensors to list, in id order.
#[derive(Debug, Clone)]
pub struct SensorQuery {
    /// Only those after this id.
    pub after: Option<String>,
    /// Only those with this status.
    pub status: Option<Status>,
    /// Only those whose id contains this text (ASCII case-insensitive).
    pub search: Option<String>,
    /// The time statuses are computed at.
    pub now: Timestamp,
    /// Page size.
    pub limit: usize,
}

/// Which calibrations of a sensor to list, newest first.
#[derive(Debug, Clone, Default)]
pub struct HistoryQuery {
    /// Only those performed at or after this instant.
    pub from: Option<Timestamp>,
    /// Only those performed at or before this instant.
    pub to: Option<Timestamp>,
    /// Keyset cursor: only calibrations after this one in the list's order
    /// (older `performed_at`, or equal and smaller id).
    pub before: Option<Uuid>,
    /// Page size.
    pub limit: usize,
}

/// An idempotency key as scoped and fingerprinted by the server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IdempotencyKey {
    /// The principal (token id) that sent it.
    pub principal: String,
    /// The client's key.
    pub key: String,
    /// `SHA-256` of the request's media type and body.
    pub request_hash: [u8; 32],
    /// The request holding the key's lease (a fresh id per request): only
    /// it may release the key, and only while it holds the lease.
    pub holder: Uuid,
}

/// A completed idempotency key, as copied from one database to another.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DoneKey {
    /// The principal that sent it.
    pub principal: String,
    /// The client's key.
    pub key: String,
    /// `SHA-256` of the request's media type and body.
    pub request_hash: [u8; 32],
    /// The calibration its request stored.
    pub calibration_id: Uuid,
    /// When it was first claimed.
    pub created_at: Timestamp,
}

/// What claiming an idempotency key found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Claim {
    /// The key is new (or its previous holder's lease expired): go ahead.
    Fresh,
    /// The same request is being processed under this key right now.
    InFlight,
    /// The key was used with a different request.
    Mismatch,
    /// The same request already stored this calibration.
    Done(Uuid),
}

/// What storing a calibration under an idempotency key did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stored {
    /// The calibration was stored.
    New,
    /// A concurrent request with the same key stored this one first; nothing
    /// new was stored.
    Existing(Uuid),
}
