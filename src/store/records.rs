//! What the store reads and writes: plain, typed records.

use accelcal_core::decision::Verdict;
use accelcal_core::{Model, TermMap};
use bytes::Bytes;
use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::StoreError;
use super::triad_elements::TriadElements;
use crate::domain::nonconformity::{
    Affected, Bearing, Nonconformity, Outcome, Replacement, bearing,
};
use crate::domain::review::{Basis, Refusal, Signature, State};
use crate::domain::status::Status;
use crate::domain::thermal::{ThermalModel, TriadThermalModel};
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
    /// A triad's elements (none for a single-axis calibration). This and
    /// the two models are boxed: inline they made every record 3.3 KB,
    /// copied whole by each future that holds one (BENCHMARKS.md "Futures
    /// and records copied"); a single axis allocates nothing for them.
    pub triad: Option<Box<TriadElements>>,
    /// A single axis's temperature model, when it is one (issue 45): its
    /// `coefficients` are then the model at `T_ref`.
    pub thermal: Option<Box<ThermalModel>>,
    /// A triad's temperature model, when it is one: its `triad` elements
    /// are then the model at `T_ref`. Kept in the same column as a single
    /// axis's ([`NewCalibration::thermal_json`]).
    pub thermal_triad: Option<Box<TriadThermalModel>>,
    /// The reference standards the test used, each with the calibration
    /// date of its certificate in force when it was performed: what the
    /// store judges against the standards' nonconformities in the
    /// transaction that stores it, holding it when one bears on it
    /// ([`crate::domain::nonconformity::bearing`]). Not a column: the
    /// result document names them; empty for a record copied or exported.
    pub standards: Vec<StandardUse>,
    /// The stored calibrations a temperature model was fitted from (its
    /// `from_calibrations`; empty for every other record): what the store
    /// checks still count, under their row locks, in the transaction that
    /// stores it ([`crate::domain::thermal::combine::unusable`]). Not a
    /// column: the result document names them.
    pub fitted_from: Vec<Uuid>,
}

/// A reference standard as a calibration used it, for the store's judgement
/// of its nonconformities.
#[derive(Debug, Clone, PartialEq)]
pub struct StandardUse {
    /// The standard.
    pub standard_id: String,
    /// When its certificate in force at the test was calibrated.
    pub calibrated_at: Timestamp,
}

impl NewCalibration {
    /// Whether this record is stored in a transaction of its own rather
    /// than in a group-committed batch: one naming standards may be stored
    /// held, and one fitted from stored calibrations locks and checks them
    /// ([`super::fitted`]) — each before anything else of its transaction.
    pub fn stored_alone(&self) -> bool {
        !self.standards.is_empty() || !self.fitted_from.is_empty()
    }

    /// The nonconformities that hold this record when it is stored: those
    /// of `found` (its standards' nonconformities) inside whose window it
    /// was performed or whose standard is out of service for it, and those
    /// `inherited` from the held calibration it supersedes whose standard
    /// it still uses; each once.
    pub fn held_by<'a>(
        &self,
        found: &'a [Nonconformity],
        inherited: &'a [Nonconformity],
    ) -> Vec<&'a Nonconformity> {
        let mut held: Vec<&Nonconformity> = found
            .iter()
            .filter(|nc| {
                self.standards.iter().any(|u| {
                    u.standard_id == nc.standard_id
                        && bearing(nc, u.calibrated_at, self.performed_at) != Bearing::Clear
                })
            })
            .collect();
        for nc in inherited {
            let uses = self
                .standards
                .iter()
                .any(|u| u.standard_id == nc.standard_id);
            if uses && !held.iter().any(|h| h.id == nc.id) {
                held.push(nc);
            }
        }
        held
    }

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
        if let Some((name, v)) = self
            .triad
            .iter()
            .flat_map(|t| t.numbers())
            .find(|(_, v)| !v.is_finite())
        {
            return Err(StoreError::Refused(format!("the triad's `{name}` is {v}")));
        }
        let axis = self.thermal.iter().flat_map(|m| m.numbers());
        let triad = self.thermal_triad.iter().flat_map(|m| m.numbers());
        if let Some((name, v)) = axis.chain(triad).find(|(_, v)| !v.is_finite()) {
            return Err(StoreError::Refused(format!(
                "the temperature model's `{name}` is {v}"
            )));
        }
        Ok(())
    }

    /// The `thermal` column: a single axis's or a triad's temperature
    /// model, as JSON (read back by [`crate::domain::thermal::AnyModel`]).
    pub fn thermal_json(&self) -> Result<Option<String>, StoreError> {
        match (&self.thermal, &self.thermal_triad) {
            (Some(m), _) => serde_json::to_string(m).map(Some),
            (None, Some(t)) => serde_json::to_string(t).map(Some),
            (None, None) => Ok(None),
        }
        .map_err(|e| StoreError::Refused(e.to_string()))
    }
}

impl From<&NewCalibration> for CalibrationSummary {
    /// The summary every engine reads back for this record once stored.
    fn from(n: &NewCalibration) -> Self {
        CalibrationSummary {
            id: n.id,
            sensor_id: n.sensor_id.clone(),
            station_id: n.station_id.clone(),
            performed_at: n.performed_at,
            received_at: n.received_at,
            unit: n.unit.clone(),
            model: n.model.clone(),
            runs: n.runs,
            coefficients: n.coefficients.clone(),
            std_errors: n.std_errors.clone(),
            sensor_type: n.sensor_type.clone(),
            verdict: n.verdict,
            due_at: n.due_at,
            expanded: n.expanded.clone(),
            triad: n.triad.clone(),
            thermal: n.thermal.clone(),
            thermal_triad: n.thermal_triad.clone(),
            state: State::Submitted,
        }
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
    /// A triad's elements (absent for a single-axis calibration, whose
    /// `coefficients` are its result; a triad's `coefficients` are empty).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub triad: Option<Box<TriadElements>>,
    /// A single axis's temperature model, when it is one (issue 45; its
    /// `coefficients` are the model at `T_ref`): served by the
    /// coefficients at a temperature and the calibration's document, not
    /// in lists.
    #[serde(skip)]
    pub thermal: Option<Box<ThermalModel>>,
    /// A triad's temperature model, when it is one (its `triad` elements
    /// are the model at `T_ref`); likewise not in lists.
    #[serde(skip)]
    pub thermal_triad: Option<Box<TriadThermalModel>>,
    /// Where it stands: `submitted`, `approved`, `rejected` or `withdrawn`
    /// (only the first two count).
    pub state: State,
}

/// One named quantity of a stored calibration, of any kind: a single
/// axis's fused coefficient (`k0`), a triad's element (`S_xy`).
#[derive(Debug, Clone, PartialEq)]
pub struct Named {
    /// Its name.
    pub name: String,
    /// Its value.
    pub value: f64,
    /// Its standard error, when stated.
    pub std_error: Option<f64>,
}

impl CalibrationSummary {
    /// Its quantities by name, in the order its kind lists them: a single
    /// axis's fused coefficients (a standard error not stored read as 0, as
    /// the history always has), a triad's `b`, `S`, `T` (and `S2`).
    pub fn quantities(&self) -> Vec<Named> {
        match &self.triad {
            Some(t) => t
                .elements()
                .into_iter()
                .map(|e| Named {
                    name: e.name,
                    value: e.value,
                    std_error: e.std_error,
                })
                .collect(),
            None => self
                .coefficients
                .iter()
                .map(|(t, v)| Named {
                    name: t.name().to_owned(),
                    value: *v,
                    std_error: Some(self.std_errors.get(t).copied().unwrap_or(0.0)),
                })
                .collect(),
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

/// A calibration made with a reference standard: what a nonconformity's
/// window holds ([`crate::domain::nonconformity`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MadeWith {
    /// The calibration.
    pub calibration_id: Uuid,
    /// Its sensor.
    pub sensor_id: String,
    /// When it was performed.
    pub performed_at: Timestamp,
    /// Its state when read.
    pub state: State,
}

impl MadeWith {
    /// What a nonconformity's list says of this calibration: found in
    /// `found`, in `now` now, standing for it `replaced_by` when superseded,
    /// and what became of it.
    pub fn affected(self, found: State, now: State, replaced_by: Option<Replacement>) -> Affected {
        Affected {
            calibration_id: self.calibration_id,
            sensor_id: self.sensor_id,
            performed_at: self.performed_at,
            state_found: found,
            state: now,
            outcome: Outcome::of(found, now, replaced_by.as_ref().map(|r| r.state)),
            replaced_by,
        }
    }

    /// [`MadeWith::affected`] from the stored name of the state it was
    /// found in (`state_found`), its state as read being its state now;
    /// without its replacement (see [`chain_end_sql`](crate::store::sql::chain_end_sql)).
    pub fn found_as(self, stored: &str) -> Result<Affected, StoreError> {
        let found = State::parse(stored)
            .ok_or_else(|| StoreError::corrupt("column `state_found`", stored.to_owned()))?;
        let now = self.state;
        Ok(self.affected(found, now, None))
    }
}

impl Affected {
    /// This entry, superseded, with what stands for it now.
    pub fn replaced(mut self, by: Replacement) -> Affected {
        self.outcome = Outcome::of(self.state_found, self.state, Some(by.state));
        self.replaced_by = Some(by);
        self
    }
}

/// What recording a signed act came to.
#[derive(Debug, Clone, PartialEq)]
pub enum Signed {
    /// Recorded: the signature, and the calibration's sensor.
    Done(Signature, String),
    /// There is no such calibration.
    NotFound,
    /// The act is not allowed ([`crate::domain::review::Act::check`]).
    Refused(Refusal),
}

/// A sensor's stored row as a write left it ([`SENSOR_ROW`](crate::store::sql::SENSOR_ROW)): its summary
/// but for the latest calibration's, which the row names by id.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorRow {
    /// The sensor.
    pub sensor_id: String,
    /// How many calibrations it has.
    pub calibration_count: u64,
    /// The earliest `performed_at`.
    pub first_performed_at: Timestamp,
    /// The latest `performed_at`.
    pub latest_performed_at: Timestamp,
    /// The latest calibration, by [`NEWEST_FIRST`](crate::store::sql::NEWEST_FIRST).
    pub latest_calibration_id: Uuid,
    /// The type assigned to it.
    pub sensor_type: Option<String>,
    /// The latest calibration's verdict.
    pub latest_verdict: Option<Verdict>,
    /// When the sensor is due, from its latest calibration.
    pub due_at: Option<Timestamp>,
}

impl SensorRow {
    /// The sensor's summary, given the calibration the row names as its
    /// latest — one of `candidates`, or `None` when it is none of them.
    /// The status is left `Unknown`: it depends on the time of a read.
    pub fn summary<'a>(
        self,
        candidates: impl IntoIterator<Item = &'a CalibrationSummary>,
    ) -> Option<SensorSummary> {
        let latest = candidates
            .into_iter()
            .find(|c| c.id == self.latest_calibration_id)?
            .clone();
        Some(SensorSummary {
            sensor_id: self.sensor_id,
            calibration_count: self.calibration_count,
            first_performed_at: self.first_performed_at,
            latest_performed_at: self.latest_performed_at,
            sensor_type: self.sensor_type,
            latest_verdict: self.latest_verdict,
            due_at: self.due_at,
            status: Status::Unknown,
            latest,
        })
    }
}

impl SensorSummary {
    /// The sensor's latest calibration that counts on `basis` and was
    /// performed strictly before `before`, when this summary can tell:
    /// its `latest` is the greatest of the calibrations that count on
    /// [`Basis::NotRejected`] by `(performed_at, id)`, so when it was
    /// performed before `before` nothing later exists to be "before" and
    /// it is the answer — the common case of a submission, which comes
    /// after its sensor's latest. `None` means: ask the records (a
    /// back-dated submission, or the approved-only basis).
    pub fn previous_before(&self, before: Timestamp, basis: Basis) -> Option<&CalibrationSummary> {
        (basis == Basis::NotRejected && self.latest.performed_at < before).then_some(&self.latest)
    }
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

/// The latest calibrations of a sensor within a window, oldest first, and
/// how many the window holds (more than `items` when the limit cut it).
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// The calibrations, oldest first.
    pub items: Vec<CalibrationSummary>,
    /// Calibrations in the window.
    pub in_window: usize,
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

#[cfg(test)]
mod tests;

/// A sensor's status as announced: its id, the status, its due date.
pub type Announced = (String, crate::domain::status::Status, Timestamp);

/// Where an endpoint stands after an attempt.
#[derive(Clone, Debug, PartialEq)]
pub struct Settle {
    /// The last event handled.
    pub cursor: i64,
    /// Failed attempts at the next.
    pub failed: i64,
    /// When the next attempt is due.
    pub next_attempt_at: Timestamp,
    /// The attempt to log, if one was made.
    pub delivery: Option<crate::domain::webhooks::Delivery>,
    /// Keep the lease, until then (more events to attempt); `None` ends it.
    pub hold_until: Option<Timestamp>,
}
