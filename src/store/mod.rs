//! Storage of calibrations and tokens behind one engine-agnostic trait.
//!
//! Handlers see only [`Store`]; each engine (SQLite today, see
//! [`sqlite::SqliteStore`]) implements it and runs the shared conformance
//! tests in `tests/store.rs`. Failures of the database itself — locked, gone,
//! read-only, full — are [`StoreError::Unavailable`], which the HTTP layer
//! answers with a retryable 503.

pub mod sqlite;

use async_trait::async_trait;
use serde::Serialize;
use serde_json::value::RawValue;
use uuid::Uuid;

use crate::auth::Role;
use crate::timestamp::Timestamp;

/// Why a storage operation failed.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The database cannot be used right now (busy, locked, missing,
    /// read-only, full, I/O error). Retryable.
    #[error("database unavailable: {0}")]
    Unavailable(String),
    /// Stored data does not decode: a bug or tampering, not retryable.
    #[error("stored data is inconsistent: {0}")]
    Corrupt(String),
}

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
    /// The model, as a JSON array.
    pub model: String,
    /// Number of runs.
    pub runs: usize,
    /// Fused coefficients, a JSON object.
    pub coefficients: String,
    /// Fused standard errors, a JSON object.
    pub std_errors: String,
    /// The whole result document (what `GET /v1/calibrations/{id}` returns).
    pub result: String,
    /// The submitted body, byte for byte.
    pub submission: Vec<u8>,
    /// The submitted body's media type.
    pub content_type: String,
    /// The principal that submitted it.
    pub submitted_by: String,
}

/// A submitted body as stored.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredSubmission {
    /// Media type it was sent with.
    pub content_type: String,
    /// The bytes.
    pub body: Vec<u8>,
}

/// A calibration without its per-run detail: what lists and control systems need.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationSummary {
    /// Calibration id.
    pub id: Uuid,
    /// The sensor.
    pub sensor_id: String,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed (canonical UTC).
    pub performed_at: String,
    /// When accelcal received it (canonical UTC).
    pub received_at: String,
    /// Output unit.
    pub unit: String,
    /// Model terms.
    pub model: Box<RawValue>,
    /// Number of runs.
    pub runs: usize,
    /// Fused coefficients.
    pub coefficients: Box<RawValue>,
    /// Fused standard errors.
    pub std_errors: Box<RawValue>,
}

/// A sensor with its calibration count and latest calibration.
#[derive(Debug, Clone, Serialize)]
pub struct SensorSummary {
    /// The sensor.
    pub sensor_id: String,
    /// Number of stored calibrations.
    pub calibration_count: u64,
    /// Earliest `performed_at`.
    pub first_performed_at: String,
    /// Latest `performed_at`.
    pub latest_performed_at: String,
    /// The calibration with the latest `performed_at` (ties: the later id).
    pub latest: CalibrationSummary,
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

/// A stored token (never its secret).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TokenRecord {
    /// Token id.
    pub id: Uuid,
    /// `SHA-256(secret)`.
    pub secret_hash: Vec<u8>,
    /// Role.
    pub role: Role,
    /// Bound station.
    pub station_id: Option<String>,
    /// Free-text label.
    pub label: Option<String>,
    /// Creation time (canonical UTC).
    pub created_at: String,
    /// Revocation time, if revoked.
    pub revoked_at: Option<String>,
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
}

/// How long idempotency keys are kept, in seconds (at least 24 h promised).
pub const IDEMPOTENCY_RETENTION_SECONDS: i64 = 48 * 3600;

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

/// The storage operations accelcal needs; one implementation per engine.
#[async_trait]
pub trait Store: Send + Sync + 'static {
    /// Checks that the database answers.
    async fn ping(&self) -> Result<(), StoreError>;
    /// Stores a calibration and updates its sensor, atomically and durably;
    /// with a key, also records the key as done in the same transaction
    /// (unless another request completed the key first).
    async fn insert_calibration(
        &self,
        c: NewCalibration,
        key: Option<IdempotencyKey>,
    ) -> Result<Stored, StoreError>;
    /// Claims an idempotency key for a request, holding it until
    /// `lease_until`; forgets keys older than the retention period.
    async fn claim_key(
        &self,
        key: IdempotencyKey,
        now: Timestamp,
        lease_until: Timestamp,
    ) -> Result<Claim, StoreError>;
    /// Gives up a claimed key whose request stored nothing.
    async fn release_key(&self, principal: String, key: String) -> Result<(), StoreError>;
    /// The result document of a calibration.
    async fn calibration_result(&self, id: Uuid) -> Result<Option<String>, StoreError>;
    /// The submitted body of a calibration.
    async fn submission(&self, id: Uuid) -> Result<Option<StoredSubmission>, StoreError>;
    /// The summary of a calibration.
    async fn calibration_summary(&self, id: Uuid)
    -> Result<Option<CalibrationSummary>, StoreError>;
    /// Sensors in `sensor_id` order, strictly after `after`.
    async fn sensors(
        &self,
        after: Option<String>,
        limit: usize,
    ) -> Result<Vec<SensorSummary>, StoreError>;
    /// One sensor.
    async fn sensor(&self, sensor_id: String) -> Result<Option<SensorSummary>, StoreError>;
    /// A sensor's calibrations, newest `performed_at` first.
    async fn history(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<CalibrationSummary>, StoreError>;
    /// Stores a new token.
    async fn insert_token(&self, t: TokenRecord) -> Result<(), StoreError>;
    /// One token by id.
    async fn token(&self, id: Uuid) -> Result<Option<TokenRecord>, StoreError>;
    /// Every token, oldest first.
    async fn tokens(&self) -> Result<Vec<TokenRecord>, StoreError>;
    /// Revokes a token; false when there is no such unrevoked token.
    async fn revoke_token(&self, id: Uuid, at: Timestamp) -> Result<bool, StoreError>;
    /// Whether an unrevoked admin token exists.
    async fn has_admin_token(&self) -> Result<bool, StoreError>;
    /// Flushes and closes (at shutdown).
    async fn close(&self);
}

/// Opens the database named by a URL: `sqlite://PATH`, `sqlite:PATH` or a
/// plain file path (SQLite).
pub fn open(url: &str) -> Result<std::sync::Arc<dyn Store>, StoreError> {
    if url.starts_with("postgres://") || url.starts_with("postgresql://") {
        return Err(StoreError::Unavailable(
            "PostgreSQL is not supported by this build; use a SQLite path".into(),
        ));
    }
    let path = url
        .strip_prefix("sqlite://")
        .or_else(|| url.strip_prefix("sqlite:"))
        .unwrap_or(url);
    Ok(std::sync::Arc::new(sqlite::SqliteStore::open(path)?))
}
