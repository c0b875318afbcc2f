//! The PostgreSQL engine: several stateless accelcal replicas on one
//! database.
//!
//! tokio-postgres with a deadpool pool ([`connect`]), TLS by rustls after the
//! URL's `sslmode`; embedded migrations under an advisory lock
//! ([`migrations`]); every write in one transaction, committed with
//! `synchronous_commit=on`, so a 201 from any replica is durable and visible
//! to every replica as soon as it is sent. Calibrations are committed many
//! to a transaction by the [`writer`] (group commit). Correct across processes, not
//! only threads: sensor summaries are row-locked upserts
//! ([`calibrations`]), idempotency keys are claimed under a row lock with a
//! lease that names its holder ([`idempotency`]). A database that restarts
//! or cannot be reached makes calls fail as [`StoreError::Unavailable`]
//! (503 with Retry-After, `/readyz` failing); the pool drops dead
//! connections and opens new ones, so the replica recovers by itself.
//! One file per concern, as the SQLite engine.

mod batch;
mod calibrations;
pub mod connect;
mod errors;
mod idempotency;
pub mod listen;
mod migrations;
mod rows;
mod sensor_types;
mod sensors;
mod sessions;
mod tokens;
pub mod writer;

use std::sync::Arc;
use std::time::Instant;

use async_trait::async_trait;
use bytes::Bytes;
use deadpool_postgres::{Object, Pool};
use uuid::Uuid;

use super::{
    CalibrationSummary, Claim, DoneKey, HistoryQuery, IdempotencyKey, NewCalibration, SensorQuery,
    SensorSummary, Series, Store, StoreError, Stored, StoredSubmission, observe,
};
use crate::domain::sensor_types::SensorType;
use crate::domain::session::SessionRecord;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::cache::{CAPACITY, CachedStore, SensorCache, TokenCache};

/// A PostgreSQL-backed [`Store`].
#[derive(Clone)]
pub struct PostgresStore {
    pool: Pool,
    writer: Arc<writer::Writer>,
}

impl PostgresStore {
    /// Connects to the database at `url` and brings its schema up to date.
    pub async fn open(url: &str) -> Result<Self, StoreError> {
        Self::open_with_queue(url, writer::QUEUE).await
    }

    /// As [`open`](Self::open), answering [`StoreError::Overloaded`] once
    /// `queue` calibrations are waiting for the [`writer`].
    pub async fn open_with_queue(url: &str, queue: usize) -> Result<Self, StoreError> {
        Self::open_with(url, queue, None).await
    }

    /// As [`open_with_queue`](Self::open_with_queue), the writer recording
    /// its batches' notifications in `echoes` for a cache's listener.
    async fn open_with(
        url: &str,
        queue: usize,
        echoes: Option<Arc<listen::Echoes>>,
    ) -> Result<Self, StoreError> {
        let pool = connect::pool(url)?;
        migrations::migrate(&pool).await?;
        let writer = Arc::new(writer::Writer::start(pool.clone(), queue, echoes));
        Ok(PostgresStore { pool, writer })
    }

    /// A replica as it serves: this engine behind a [`SensorCache`] and a
    /// [`TokenCache`], which a listener keeps in step with other replicas'
    /// writes (ignoring the echoes of this one's batches).
    pub async fn cached(url: &str) -> Result<CachedStore, StoreError> {
        let echoes = Arc::new(listen::Echoes::default());
        let inner = Arc::new(Self::open_with(url, writer::QUEUE, Some(echoes.clone())).await?);
        let cache = Arc::new(SensorCache::new(CAPACITY, false));
        let tokens = Arc::new(TokenCache::new(
            crate::store::cache::tokens::CAPACITY,
            false,
        ));
        let listener = listen::spawn(url.to_owned(), cache.clone(), tokens.clone(), echoes);
        Ok(CachedStore::new(inner, cache, tokens, Some(listener)))
    }

    /// The group-commit writer (how many writes wait, how many batches
    /// committed).
    pub fn writer(&self) -> &writer::Writer {
        &self.writer
    }

    /// A run-time setting as a pooled connection sees it (`synchronous_commit`,
    /// …): for diagnostics and the tests that check every connection is
    /// durable.
    pub async fn session_setting(&self, name: &str) -> Result<String, StoreError> {
        let c = self.client().await?;
        let row = c
            .query_one("SELECT current_setting($1)", &[&name])
            .await
            .map_err(errors::map)?;
        Ok(row.get(0))
    }

    /// Whether a pooled connection is encrypted (TLS), as the server sees it.
    pub async fn encrypted(&self) -> Result<bool, StoreError> {
        let c = self.client().await?;
        let row = c
            .query_one(
                "SELECT coalesce((SELECT ssl FROM pg_stat_ssl WHERE pid = pg_backend_pid()), false)",
                &[],
            )
            .await
            .map_err(errors::map)?;
        Ok(row.get(0))
    }

    async fn client(&self) -> Result<Object, StoreError> {
        self.pool.get().await.map_err(errors::pool)
    }
}

/// Runs one timed operation on a pooled connection.
macro_rules! op {
    ($self:ident, $name:literal, |$c:ident| $body:expr) => {{
        let started = Instant::now();
        let out = async {
            #[allow(unused_mut)]
            let mut $c = $self.client().await?;
            $body
        }
        .await;
        observe($name, started, &out);
        out
    }};
}

#[async_trait]
impl Store for PostgresStore {
    async fn ping(&self) -> Result<(), StoreError> {
        op!(self, "ping", |c| {
            c.simple_query("SELECT 1").await.map_err(errors::map)?;
            Ok(())
        })
    }

    async fn insert_calibration(
        &self,
        n: NewCalibration,
        key: Option<IdempotencyKey>,
    ) -> Result<Stored, StoreError> {
        let started = Instant::now();
        let out = match calibrations::Row::new(n) {
            Ok(row) => self.writer.insert(row, key).await,
            Err(e) => Err(e),
        };
        observe("insert_calibration", started, &out);
        out
    }

    async fn claim_key(
        &self,
        k: IdempotencyKey,
        now: Timestamp,
        lease_until: Timestamp,
    ) -> Result<Claim, StoreError> {
        op!(self, "claim_key", |c| idempotency::claim(
            &mut c,
            &k,
            now,
            lease_until
        )
        .await)
    }

    async fn release_key(&self, k: IdempotencyKey) -> Result<(), StoreError> {
        op!(self, "release_key", |c| idempotency::release(&c, &k).await)
    }

    async fn calibration_result(&self, id: Uuid) -> Result<Option<Bytes>, StoreError> {
        op!(self, "calibration_result", |c| calibrations::result(&c, id)
            .await)
    }

    async fn submission(&self, id: Uuid) -> Result<Option<StoredSubmission>, StoreError> {
        op!(self, "submission", |c| calibrations::submission(&c, id)
            .await)
    }

    async fn calibration_summary(
        &self,
        id: Uuid,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        op!(self, "calibration_summary", |c| calibrations::summary(
            &c, id
        )
        .await)
    }

    async fn sensors(&self, q: SensorQuery) -> Result<Vec<SensorSummary>, StoreError> {
        op!(self, "sensors", |c| sensors::list(&c, &q).await)
    }

    async fn sensor(
        &self,
        sensor_id: String,
        now: Timestamp,
    ) -> Result<Option<SensorSummary>, StoreError> {
        op!(self, "sensor", |c| sensors::get(&c, &sensor_id, now).await)
    }

    async fn series(
        &self,
        sensor_id: String,
        from: Option<Timestamp>,
        to: Option<Timestamp>,
        limit: usize,
    ) -> Result<Series, StoreError> {
        op!(self, "series", |c| calibrations::series(
            &c, &sensor_id, from, to, limit
        )
        .await)
    }

    async fn previous_calibration(
        &self,
        sensor_id: String,
        before: Timestamp,
    ) -> Result<Option<CalibrationSummary>, StoreError> {
        op!(self, "previous_calibration", |c| calibrations::previous(
            &c, &sensor_id, before
        )
        .await)
    }

    async fn put_sensor_type(&self, t: SensorType) -> Result<bool, StoreError> {
        op!(self, "put_sensor_type", |c| sensor_types::put(&c, &t).await)
    }

    async fn sensor_type(&self, type_id: String) -> Result<Option<SensorType>, StoreError> {
        op!(self, "sensor_type", |c| sensor_types::get(&c, &type_id)
            .await)
    }

    async fn sensor_types(&self) -> Result<Vec<SensorType>, StoreError> {
        op!(self, "sensor_types", |c| sensor_types::list(&c).await)
    }

    async fn assign_sensor_type(
        &self,
        sensor_id: String,
        type_id: String,
    ) -> Result<bool, StoreError> {
        op!(self, "assign_sensor_type", |c| sensors::assign_type(
            &c, &sensor_id, &type_id
        )
        .await)
    }

    async fn history(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<CalibrationSummary>, StoreError> {
        op!(self, "history", |c| calibrations::history(
            &c, &sensor_id, &q
        )
        .await)
    }

    async fn history_ids(
        &self,
        sensor_id: String,
        q: HistoryQuery,
    ) -> Result<Vec<Uuid>, StoreError> {
        op!(self, "history_ids", |c| calibrations::history_ids(
            &c, &sensor_id, &q
        )
        .await)
    }

    async fn insert_token(&self, t: TokenRecord) -> Result<(), StoreError> {
        op!(self, "insert_token", |c| tokens::insert(&c, &t).await)
    }

    async fn token(&self, id: Uuid) -> Result<Option<TokenRecord>, StoreError> {
        op!(self, "token", |c| tokens::get(&c, id).await)
    }

    async fn tokens(&self) -> Result<Vec<TokenRecord>, StoreError> {
        op!(self, "tokens", |c| tokens::list(&c).await)
    }

    async fn revoke_token(&self, id: Uuid, at: Timestamp) -> Result<bool, StoreError> {
        op!(self, "revoke_token", |c| tokens::revoke(&c, id, at).await)
    }

    async fn import_in_progress(&self) -> Result<Option<String>, StoreError> {
        op!(self, "import_in_progress", |c| {
            let row = c
                .query_opt("SELECT description FROM import_in_progress", &[])
                .await
                .map_err(errors::map)?;
            Ok(row.map(|r| r.get(0)))
        })
    }

    async fn set_import_in_progress(&self, import: Option<String>) -> Result<(), StoreError> {
        op!(self, "set_import_in_progress", |c| {
            let done = match &import {
                Some(d) => {
                    c.execute(
                        "INSERT INTO import_in_progress (singleton, description) VALUES (1, $1) \
                         ON CONFLICT (singleton) DO UPDATE SET description = excluded.description",
                        &[d],
                    )
                    .await
                }
                None => c.execute("DELETE FROM import_in_progress", &[]).await,
            };
            done.map(|_| ()).map_err(errors::map)
        })
    }

    async fn has_admin_token(&self) -> Result<bool, StoreError> {
        op!(self, "has_admin_token", |c| tokens::has_admin(&c).await)
    }

    async fn insert_session(&self, s: SessionRecord) -> Result<(), StoreError> {
        op!(self, "insert_session", |c| sessions::insert(&mut c, &s)
            .await)
    }

    async fn session(&self, id_hash: [u8; 32]) -> Result<Option<SessionRecord>, StoreError> {
        op!(self, "session", |c| sessions::get(&c, id_hash).await)
    }

    async fn delete_session(&self, id_hash: [u8; 32]) -> Result<bool, StoreError> {
        op!(self, "delete_session", |c| sessions::delete(&c, id_hash)
            .await)
    }

    async fn is_empty(&self) -> Result<bool, StoreError> {
        op!(self, "is_empty", |c| {
            let row = c
                .query_one(
                    "SELECT NOT (EXISTS (SELECT 1 FROM calibrations) OR EXISTS (SELECT 1 FROM tokens) \
                     OR EXISTS (SELECT 1 FROM sensor_types))",
                    &[],
                )
                .await
                .map_err(errors::map)?;
            Ok(row.get(0))
        })
    }

    async fn export_calibrations(
        &self,
        after: Option<Uuid>,
        limit: usize,
    ) -> Result<Vec<NewCalibration>, StoreError> {
        op!(self, "export_calibrations", |c| calibrations::export(
            &c, after, limit
        )
        .await)
    }

    async fn done_keys(&self, since: Timestamp) -> Result<Vec<DoneKey>, StoreError> {
        op!(self, "done_keys", |c| idempotency::done(&c, since).await)
    }

    async fn put_done_key(&self, k: DoneKey) -> Result<(), StoreError> {
        op!(self, "put_done_key", |c| idempotency::put_done(&c, &k)
            .await)
    }

    async fn close(&self) {
        self.pool.close();
    }
}
