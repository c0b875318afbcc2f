//! Storage of calibrations, sensors, tokens and idempotency keys behind
//! engine-agnostic traits, one per concern.
//!
//! Handlers see only [`Store`], the sum of the concerns; each engine
//! (PostgreSQL, and SQLite, see [`sqlite::SqliteStore`]) implements every
//! concern in the file of that concern, each method's body being its query,
//! and runs the shared conformance tests in `tests/store/`; [`open`] gives
//! it its [`cache::Cache`], which it asks itself where a read is cached.
//! Failures of the database itself — locked, gone,
//! read-only, full — are [`StoreError::Unavailable`], which the HTTP layer
//! answers with a retryable 503. A new engine goes in a folder of its own
//! beside `sqlite/`, with its migrations, one file per concern, and one line
//! in [`open`].

pub mod audit;
pub mod cache;
pub mod conditional;
pub mod copy;
mod error;
pub(crate) mod fitted;
pub mod issued;
pub mod postgres;
mod records;
pub(crate) mod sql;
pub mod sqlite;
mod triad_elements;
pub mod verify;

use std::sync::Arc;

use async_trait::async_trait;
use uuid::Uuid;

pub use audit::AuditQuery;
pub use conditional::{Precondition, Put};
pub use error::{BoxError, StoreError};
pub use issued::{IssuedCertificate, Render, Rendered, Revision};
pub use records::*;
pub use sql::*;
pub use triad_elements::*;

use crate::domain::audit::{Actor, Entry};
use crate::domain::customers::{Customer, Item};
use crate::domain::nonconformity::{Affected, Nonconformity, Traced};
use crate::domain::review::{Act, Basis, Signature, State};
use crate::domain::sensor_types::SensorType;
use crate::domain::session::SessionRecord;
use crate::domain::standards::Standard;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::domain::webhooks::{Definition, Delivery, Endpoint, Secret};

/// How long idempotency keys are kept, in seconds (at least 24 h promised).
pub const IDEMPOTENCY_RETENTION_SECONDS: i64 = 48 * 3600;

/// Everything accelcal stores: one trait per concern, each implemented by
/// each engine in the file of that concern (`sqlite/tokens.rs` holds
/// `impl Tokens for SqliteStore`, its method bodies the queries). Handlers
/// hold an `Arc<dyn Store>` and bring the concerns they use into scope
/// ([`prelude`]).
pub trait Store:
    Database
    + Audit
    + Calibrations
    + Reviews
    + Certificates
    + Customers
    + Sensors
    + SensorTypes
    + Standards
    + Tokens
    + Sessions
    + Idempotency
    + Webhooks
{
}

impl<T> Store for T where
    T: Database
        + Audit
        + Calibrations
        + Reviews
        + Certificates
        + Customers
        + Sensors
        + SensorTypes
        + Standards
        + Tokens
        + Sessions
        + Idempotency
        + Webhooks
{
}

/// Every concern trait, for `use crate::store::prelude::*`.
pub mod prelude {
    pub use super::{
        Audit, Calibrations, Certificates, Customers, Database, Idempotency, Reviews, SensorTypes,
        Sensors, Sessions, Standards, Store, Tokens, Webhooks,
    };
}

/// The database itself: whether it answers, what it holds, its backup and
/// its end.
#[async_trait]
pub trait Database: Send + Sync + 'static {
    /// Checks that the database answers.
    async fn ping(&self) -> Result<(), StoreError>;
    /// Whether the database holds no calibration, token, sensor type,
    /// standard, customer or item.
    async fn is_empty(&self) -> Result<bool, StoreError>;
    /// The description of an `accelcal migrate` into this database that has
    /// not finished, if there is one.
    async fn import_in_progress(&self) -> Result<Option<String>, StoreError>;
    /// Marks an import into this database as under way (`Some`, described)
    /// or finished (`None`).
    async fn set_import_in_progress(&self, import: Option<String>) -> Result<(), StoreError>;
    /// A consistent copy of the whole database as one SQLite file, written
    /// into a new temporary file beside the database (removed when the
    /// handle is dropped); `None` for an engine with its own tools
    /// (PostgreSQL: `pg_dump`).
    async fn backup(&self) -> Result<Option<tempfile::NamedTempFile>, StoreError> {
        Ok(None)
    }
    /// Flushes and closes (at shutdown).
    async fn close(&self);
}

/// The audit trail ([`crate::domain::audit`]): every method below that
/// changes what is stored appends its entry in its own transaction (a
/// calibration stored, a signature, a token issued or revoked, a definition
/// put, a sensor retyped), with the actor it is given or, for a
/// submission, its token's; here it is read.
#[async_trait]
pub trait Audit: Send + Sync + 'static {
    /// The entries `q` selects, in sequence order.
    async fn audit(&self, q: AuditQuery) -> Result<Vec<Entry>, StoreError>;
    /// The sealed entries after `after`, in sequence order, at most
    /// `limit` — without sealing first (what the live events read, often:
    /// on PostgreSQL an entry is sealed within moments of its act's commit,
    /// [`crate::store::postgres`]'s sealer). Sealed entries only ever
    /// follow the head, so a reader that resumes after the last it read
    /// misses none.
    async fn sealed_after(&self, after: i64, limit: usize) -> Result<Vec<Entry>, StoreError>;
    /// The last sealed entry's sequence number (0 for an empty trail).
    async fn audit_head(&self) -> Result<i64, StoreError>;
    /// A counter that moves soon after this process's own acts' entries
    /// have joined the chain — so that a reader of
    /// [`sealed_after`](Self::sealed_after) need not wait for its next look; each reader
    /// takes its own receiver (every one sees every change); `None` when
    /// the engine cannot tell.
    fn trail_grew(&self) -> Option<tokio::sync::watch::Receiver<u64>> {
        None
    }
    /// Appends `events`, in order, in one transaction (`accelcal audit
    /// adopt`: the rows a database held before its trail).
    async fn record(&self, events: Vec<crate::domain::audit::Event>) -> Result<(), StoreError>;
    /// Entries of committed acts not yet sealed into the chain (on
    /// PostgreSQL, where a sealer chains them shortly after each commit;
    /// always 0 on SQLite, whose single writer chains them in the act's
    /// transaction).
    async fn unsealed(&self) -> Result<i64, StoreError> {
        Ok(0)
    }
    /// Appends `service.configure` with `settings` (the settings that change
    /// decisions) unless the last such entry recorded the same; true when
    /// it appended.
    async fn configure(
        &self,
        settings: serde_json::Map<String, serde_json::Value>,
    ) -> Result<bool, StoreError>;
}

/// Calibrations: the durable insert and every read of them.
#[async_trait]
pub trait Calibrations: Send + Sync + 'static {
    /// Stores a calibration and updates its sensor, atomically and durably;
    /// with a key, also records the key as done in the same transaction
    /// (unless another request completed the key first). A calibration
    /// naming standards is judged against their nonconformities in that
    /// transaction and stored held (`under_review`) when one bears on it
    /// ([`NewCalibration::standards`]). Refuses a record holding a
    /// non-finite number ([`NewCalibration::check`]).
    async fn insert_calibration(
        &self,
        c: NewCalibration,
        key: Option<IdempotencyKey>,
    ) -> Result<Stored, StoreError>;
    /// The result document of a calibration (JSON, as answered when stored).
    async fn calibration_result(&self, id: Uuid) -> Result<Option<bytes::Bytes>, StoreError>;
    /// The submitted body of a calibration.
    async fn submission(&self, id: Uuid) -> Result<Option<StoredSubmission>, StoreError>;
    /// The summary of a calibration.
    async fn calibration_summary(&self, id: Uuid)
    -> Result<Option<CalibrationSummary>, StoreError>;
    /// A sensor's calibrations, newest `performed_at` first.
    async fn history(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<CalibrationSummary>, StoreError>;
    /// The ids and states of the calibrations [`Calibrations::history`]
    /// answers for `q`, in its order: what a reader needs when it keeps the
    /// summaries rendered by id and state (a stored calibration never
    /// changes; only its state does).
    async fn history_ids(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<(Uuid, State)>, StoreError>;
    /// A sensor's latest `limit` calibrations that count on `basis`,
    /// performed within `from..=to`, oldest first (ties by id), and how many
    /// the window holds: the series of its stability.
    async fn series(
        &self,
        sensor_id: String,
        from: Option<Timestamp>,
        to: Option<Timestamp>,
        limit: usize,
        basis: Basis,
    ) -> Result<Series, StoreError>;
    /// The sensor's calibration that counts on `basis` with the latest
    /// `performed_at` strictly before `before` (ties: the larger id).
    async fn previous_calibration(
        &self,
        sensor_id: String,
        before: Timestamp,
        basis: Basis,
    ) -> Result<Option<CalibrationSummary>, StoreError>;
    /// The sensor's latest approved calibration (what serves with
    /// `--require-approval`; without it the sensor's own latest does).
    async fn latest_approved(
        &self,
        sensor_id: String,
    ) -> Result<Option<CalibrationSummary>, StoreError>;
    /// Whole calibrations in id order, after `after` (for `accelcal migrate`).
    async fn export_calibrations(
        &self,
        after: Option<Uuid>,
        limit: usize,
    ) -> Result<Vec<NewCalibration>, StoreError>;
}

/// Review: the signed acts on a calibration that change its state
/// ([`crate::domain::review`]).
#[async_trait]
pub trait Reviews: Send + Sync + 'static {
    /// Records `act` on calibration `id`: in one transaction, reads its
    /// state and who submitted it, checks the act ([`Act::check`]), appends
    /// the signature and computes its sensor's row again
    /// ([`sensor_recompute`]); the sensor's cached summary is dropped.
    async fn sign(&self, id: Uuid, act: Act) -> Result<Signed, StoreError>;
    /// Supersedes calibration `id` by `replacement`: as [`Reviews::sign`]
    /// with a `supersede` act, storing the replacement (a new calibration,
    /// of any sensor) in the same transaction — both or neither.
    async fn supersede(
        &self,
        id: Uuid,
        replacement: NewCalibration,
        act: Act,
    ) -> Result<Signed, StoreError>;
    /// [`Reviews::sign`] of an approval that issues the certificate: in the
    /// same transaction, when the calibration has no issued certificate yet,
    /// `render` renders it with the signatures the approval leaves and it is
    /// stored as revision 1, the approval's audit entry carrying the SHA-256
    /// of each document ([`issued`]).
    async fn approve_issuing(
        &self,
        id: Uuid,
        act: Act,
        render: Render,
    ) -> Result<Signed, StoreError>;
    /// A calibration's signatures, in order (none for an unknown one).
    async fn signatures(&self, id: Uuid) -> Result<Vec<Signature>, StoreError>;
    /// The calibrations performed with standard `standard_id` within
    /// `from..=to`, oldest first.
    async fn made_with(
        &self,
        standard_id: String,
        from: Timestamp,
        to: Timestamp,
    ) -> Result<Vec<MadeWith>, StoreError>;
    /// Records the nonconformity `nc` and, in the same transaction, `hold`s
    /// each calibration made with its standard in its window
    /// ([`Reviews::made_with`], read in that transaction) that counts
    /// (`act` signed for each: an admin's `hold`); the others are listed
    /// and left. Serialised with every store of a calibration naming the
    /// standard (which judges the standard's nonconformities in its own
    /// transaction), so that none is stored unheld in between. Answers each
    /// calibration with its state then and now.
    async fn hold(&self, nc: Nonconformity, act: Act) -> Result<Vec<Affected>, StoreError>;
    /// The nonconformities recorded of any of `standard_ids`, without their
    /// calibrations, oldest `found_at` first.
    async fn findings(&self, standard_ids: Vec<String>) -> Result<Vec<Nonconformity>, StoreError>;
    /// Stores a nonconformity as another database recorded it, with the
    /// calibrations of its window and their states then, holding nothing
    /// (`accelcal migrate`: the holds come across as signatures).
    async fn put_nonconformity(&self, t: Traced) -> Result<(), StoreError>;
    /// A standard's nonconformities, oldest `found_at` first, each with its
    /// calibrations as they stand now (a superseded one with the last of
    /// its replacements).
    async fn nonconformities(&self, standard_id: String) -> Result<Vec<Traced>, StoreError>;
}

/// Issued certificates ([`issued`]): frozen revisions of each approved
/// calibration's certificate.
#[async_trait]
pub trait Certificates: Send + Sync + 'static {
    /// Revision `revision` of calibration `id`'s issued certificate, else
    /// its latest; none when it has no such revision.
    async fn certificate(
        &self,
        id: Uuid,
        revision: Option<u32>,
    ) -> Result<Option<IssuedCertificate>, StoreError>;
    /// Every revision of calibration `id`'s certificate, without the
    /// documents, oldest first.
    async fn revisions(&self, id: Uuid) -> Result<Vec<Revision>, StoreError>;
    /// Stores `c`, when the latest revision is `c.revision − 1` (none for
    /// revision 1), and appends `certificate.issue` (revision 1: a
    /// calibration approved before certificates were issued at approval) or
    /// `certificate.amend` with its digests and reason; false, writing
    /// nothing, when another revision got there first.
    async fn issue_certificate(&self, c: IssuedCertificate) -> Result<bool, StoreError>;
}

/// Sensors: each one's summary with its latest calibration, and its type.
#[async_trait]
pub trait Sensors: Send + Sync + 'static {
    /// Sensors in `sensor_id` order, strictly after `after`, of a status.
    async fn sensors(&self, q: SensorQuery) -> Result<Vec<SensorSummary>, StoreError>;
    /// One sensor, its status computed at `now`.
    async fn sensor(
        &self,
        sensor_id: String,
        now: Timestamp,
    ) -> Result<Option<SensorSummary>, StoreError>;
    /// The id and state of a sensor's latest calibration (the one
    /// [`Sensors::sensor`] reports), `None` for an unknown sensor.
    async fn latest_calibration_id(
        &self,
        sensor_id: String,
    ) -> Result<Option<(Uuid, State)>, StoreError>;
    /// The status last announced for each sensor, and the due date it was
    /// announced for ([`Sensors::announce_statuses`]).
    async fn announced_statuses(&self) -> Result<Vec<Announced>, StoreError>;
    /// Announces each sensor's status by the clock: for each whose
    /// announced status or due date differs, records it and appends
    /// `sensor.status`, in one transaction; answers how many it announced.
    /// Two replicas announcing the same change at once announce it once.
    async fn announce_statuses(
        &self,
        now: Vec<Announced>,
        at: Timestamp,
    ) -> Result<usize, StoreError>;
    /// Assigns an existing type to an existing sensor; false when there is
    /// no such sensor.
    async fn assign_sensor_type(
        &self,
        sensor_id: String,
        type_id: String,
        by: Actor,
    ) -> Result<bool, StoreError>;
}

/// Sensor types: limits, intervals and the model they ask for.
#[async_trait]
pub trait SensorTypes: Send + Sync + 'static {
    /// Creates or replaces a sensor type, if `pre` holds
    /// ([`conditional`]).
    async fn put_sensor_type(
        &self,
        t: SensorType,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<SensorType>, StoreError>;
    /// One sensor type.
    async fn sensor_type(&self, type_id: String) -> Result<Option<SensorType>, StoreError>;
    /// Every sensor type, in id order.
    async fn sensor_types(&self) -> Result<Vec<SensorType>, StoreError>;
}

/// Reference standards: stands, reference accelerometers, thermometers,
/// gravity values.
#[async_trait]
pub trait Standards: Send + Sync + 'static {
    /// Creates or replaces a standard, if `pre` holds ([`conditional`]):
    /// the standard it replaces, read in the same transaction, gives its
    /// certificate to the new one's earlier ones when they differ
    /// ([`Standard::replacing`]).
    async fn put_standard(
        &self,
        s: Standard,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Standard>, StoreError>;
    /// One standard.
    async fn standard(&self, standard_id: String) -> Result<Option<Standard>, StoreError>;
    /// Every standard, in id order.
    async fn standards(&self) -> Result<Vec<Standard>, StoreError>;
}

/// Customers, and the items behind sensor ids (issue 29).
#[async_trait]
pub trait Customers: Send + Sync + 'static {
    /// Creates or replaces a customer, if `pre` holds ([`conditional`]).
    async fn put_customer(
        &self,
        c: Customer,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Customer>, StoreError>;
    /// One customer.
    async fn customer(&self, customer_id: String) -> Result<Option<Customer>, StoreError>;
    /// Every customer, in id order.
    async fn customers(&self) -> Result<Vec<Customer>, StoreError>;
    /// Creates or replaces the item behind a sensor id, if `pre` holds
    /// ([`conditional`]).
    async fn put_item(
        &self,
        i: Item,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Item>, StoreError>;
    /// The item behind a sensor id.
    async fn item(&self, sensor_id: String) -> Result<Option<Item>, StoreError>;
    /// Every item, in sensor id order.
    async fn items(&self) -> Result<Vec<Item>, StoreError>;
}

/// Issued tokens (only the hash of each secret).
#[async_trait]
pub trait Tokens: Send + Sync + 'static {
    /// Stores a new token.
    async fn insert_token(&self, t: TokenRecord, by: Actor) -> Result<(), StoreError>;
    /// One token by id.
    async fn token(&self, id: Uuid) -> Result<Option<TokenRecord>, StoreError>;
    /// Every token, oldest first.
    async fn tokens(&self) -> Result<Vec<TokenRecord>, StoreError>;
    /// Revokes a token; false when there is no such unrevoked token.
    async fn revoke_token(&self, id: Uuid, at: Timestamp, by: Actor) -> Result<bool, StoreError>;
    /// Whether an unrevoked admin token exists.
    async fn has_admin_token(&self) -> Result<bool, StoreError>;
}

/// Web sessions (only the hash of each id).
#[async_trait]
pub trait Sessions: Send + Sync + 'static {
    /// Opens a web session, forgetting every session expired by its
    /// `created_at`.
    async fn insert_session(&self, s: SessionRecord) -> Result<(), StoreError>;
    /// One session by the hash of its id (expired or not: the caller judges).
    async fn session(&self, id_hash: [u8; 32]) -> Result<Option<SessionRecord>, StoreError>;
    /// Ends a session; false when there was none.
    async fn delete_session(&self, id_hash: [u8; 32]) -> Result<bool, StoreError>;
}

/// Webhook endpoints and where their deliveries stand
/// ([`crate::domain::webhooks`]); registering, changing, rotating,
/// redelivering and deleting each append their audit entry.
#[async_trait]
pub trait Webhooks: Send + Sync + 'static {
    /// Registers `def` (true) with `secret`, its deliveries starting after
    /// event `head`; or changes an endpoint of that id (false), keeping its
    /// secrets and where its deliveries stand.
    async fn put_webhook(
        &self,
        def: Definition,
        secret: Secret,
        head: i64,
        at: Timestamp,
        by: Actor,
    ) -> Result<(Endpoint, bool), StoreError>;
    /// One endpoint.
    async fn webhook(&self, id: String) -> Result<Option<Endpoint>, StoreError>;
    /// Every endpoint, in id order.
    async fn webhooks(&self) -> Result<Vec<Endpoint>, StoreError>;
    /// Deletes an endpoint and its log; false when there is none.
    async fn delete_webhook(
        &self,
        id: String,
        at: Timestamp,
        by: Actor,
    ) -> Result<bool, StoreError>;
    /// Makes `secret` the endpoint's, the one it replaces signing beside it
    /// until `overlap_until`; `None` when there is no such endpoint.
    async fn rotate_webhook(
        &self,
        id: String,
        secret: Secret,
        overlap_until: Timestamp,
        at: Timestamp,
        by: Actor,
    ) -> Result<Option<Endpoint>, StoreError>;
    /// Sets the endpoint's deliveries to start again after event `after`,
    /// due at once (and ends any lease on it); `None` when there is none.
    async fn redeliver_webhook(
        &self,
        id: String,
        after: i64,
        at: Timestamp,
        by: Actor,
    ) -> Result<Option<Endpoint>, StoreError>;
    /// Leases one endpoint with events to deliver — its cursor before
    /// `head`, its next attempt due at `now`, no lease on it unexpired —
    /// to `lease.0` until `lease.1`: the one due longest. One holder at a
    /// time, across replicas.
    async fn claim_webhook(
        &self,
        head: i64,
        now: Timestamp,
        lease: (Uuid, Timestamp),
    ) -> Result<Option<Endpoint>, StoreError>;
    /// Records where the endpoint stands after an attempt (and logs it), if
    /// `holder` still holds its lease, and ends the lease or renews it
    /// (`s.hold_until`); the attempt is logged either way. False when the
    /// lease was lost (redelivered or deleted meanwhile).
    async fn settle_webhook(&self, id: String, holder: Uuid, s: Settle)
    -> Result<bool, StoreError>;
    /// The endpoint's newest `limit` attempts, newest first.
    async fn deliveries(&self, id: String, limit: usize) -> Result<Vec<Delivery>, StoreError>;
}

/// Idempotency keys: claimed with a lease, completed with their calibration.
#[async_trait]
pub trait Idempotency: Send + Sync + 'static {
    /// Claims an idempotency key for a request, holding it until
    /// `lease_until`; forgets keys older than the retention period.
    async fn claim_key(
        &self,
        key: IdempotencyKey,
        now: Timestamp,
        lease_until: Timestamp,
    ) -> Result<Claim, StoreError>;
    /// Gives up a claimed key whose request stored nothing — unless another
    /// request has since taken the lease over (`key.holder` no longer holds it).
    async fn release_key(&self, key: IdempotencyKey) -> Result<(), StoreError>;
    /// Completed idempotency keys created at or after `since`.
    async fn done_keys(&self, since: Timestamp) -> Result<Vec<DoneKey>, StoreError>;
    /// Stores a completed idempotency key (its calibration stored first).
    async fn put_done_key(&self, k: DoneKey) -> Result<(), StoreError>;
}

/// Records one storage operation's latency in
/// `accelcal_storage_operation_duration_seconds{operation, outcome}`, the
/// outcome being `ok`, `unavailable` (the database), `constraint`, `corrupt`,
/// `refused`, `overloaded` (the write queue was full) or `conflict` (what a
/// record was made from changed before it was stored). Every engine calls it.
pub fn observe<T>(
    operation: &'static str,
    started: std::time::Instant,
    out: &Result<T, StoreError>,
) {
    let outcome = match out {
        Ok(_) => "ok",
        Err(StoreError::Unavailable(_)) => "unavailable",
        Err(StoreError::Constraint(_)) => "constraint",
        Err(StoreError::Corrupt { .. }) => "corrupt",
        Err(StoreError::Refused(_)) => "refused",
        Err(StoreError::Overloaded(_)) => "overloaded",
        Err(StoreError::Conflict(_)) => "conflict",
    };
    metrics::histogram!(
        "accelcal_storage_operation_duration_seconds",
        "operation" => operation,
        "outcome" => outcome
    )
    .record(started.elapsed().as_secs_f64());
}

/// Opens the database named by a URL — `postgres://…` or `postgresql://…`
/// (PostgreSQL), `sqlite://PATH`, `sqlite:PATH` or a plain file path
/// (SQLite) — brings its schema up to date, and gives the engine its cache
/// ([`cache`]): for PostgreSQL with its listener, so that writes by other
/// replicas reach it.
pub async fn open(url: &str) -> Result<Arc<dyn Store>, StoreError> {
    open_with(url, sqlite::MIN_FREE_BYTES).await
}

/// [`open`], a SQLite database ready only while its disk has `min_free`
/// bytes free.
pub async fn open_with(url: &str, min_free: u64) -> Result<Arc<dyn Store>, StoreError> {
    if url.starts_with("postgres://") || url.starts_with("postgresql://") {
        return Ok(Arc::new(postgres::PostgresStore::cached(url).await?));
    }
    let path = url
        .strip_prefix("sqlite://")
        .or_else(|| url.strip_prefix("sqlite:"))
        .unwrap_or(url);
    Ok(Arc::new(
        sqlite::SqliteStore::open(path)?
            .with_min_free(min_free)
            .cached(),
    ))
}
