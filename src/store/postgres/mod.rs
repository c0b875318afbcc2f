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

/// Runs one timed operation on a pooled connection.
macro_rules! op {
    ($self:ident, $name:literal, |$c:ident| $body:expr) => {{
        let started = std::time::Instant::now();
        let out = async {
            #[allow(unused_mut)]
            let mut $c = $self.client().await?;
            $body
        }
        .await;
        $crate::store::observe($name, started, &out);
        out
    }};
}

/// [`op!`] of an act: one that writes audit entries, so that, once its
/// transaction has committed, this replica's sealer is woken to chain them
/// ([`seal`]).
macro_rules! act {
    ($self:ident, $name:literal, |$c:ident| $body:expr) => {{
        let out = op!($self, $name, |$c| $body);
        if out.is_ok() {
            $self.sealer.wake();
        }
        out
    }};
}

mod audit;
mod batch;
mod calibrations;
mod certificates;
pub mod connect;
mod customers;
mod definitions;
mod errors;
mod fitted;
mod holds;
mod idempotency;
pub mod listen;
mod migrations;
mod reviews;
mod rows;
mod seal;
mod sensor_types;
mod sensors;
mod sessions;
mod signatures;
mod standards;
mod tokens;
mod webhooks;
pub mod writer;

use std::sync::Arc;

use async_trait::async_trait;
use deadpool_postgres::{Object, Pool};

use super::cache::Cache;
use super::{Database, StoreError};

/// A PostgreSQL-backed [`Store`](super::Store).
#[derive(Clone)]
pub struct PostgresStore {
    pool: Pool,
    writer: Arc<writer::Writer>,
    sealer: Arc<seal::Sealer>,
    /// Off unless [`cached`](Self::cached).
    cache: Arc<Cache>,
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
        let sealer = Arc::new(seal::Sealer::start(pool.clone()));
        let writer = Arc::new(writer::Writer::start(
            pool.clone(),
            queue,
            echoes,
            sealer.waker(),
        ));
        Ok(PostgresStore {
            pool,
            writer,
            sealer,
            cache: Arc::new(Cache::off()),
        })
    }

    /// A replica as it serves: with a [`Cache`] in front of its sensor and
    /// token reads, which a listener keeps in step with other replicas'
    /// writes (ignoring the echoes of this one's batches).
    pub async fn cached(url: &str) -> Result<Self, StoreError> {
        let echoes = Arc::new(listen::Echoes::default());
        let mut store = Self::open_with(url, writer::QUEUE, Some(echoes.clone())).await?;
        let cache = Cache::new(false);
        let listener = listen::spawn(
            url.to_owned(),
            cache.sensors().clone(),
            cache.tokens().clone(),
            echoes,
        );
        store.cache = Arc::new(cache.listening(listener));
        Ok(store)
    }

    /// The cache (for tests).
    pub fn cache(&self) -> &Cache {
        &self.cache
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

#[async_trait]
impl Database for PostgresStore {
    async fn ping(&self) -> Result<(), StoreError> {
        op!(self, "ping", |c| {
            c.simple_query("SELECT 1").await.map_err(errors::map)?;
            Ok(())
        })
    }

    async fn is_empty(&self) -> Result<bool, StoreError> {
        op!(self, "is_empty", |c| {
            let row = c
                .query_one(
                    "SELECT NOT (EXISTS (SELECT 1 FROM calibrations) OR EXISTS (SELECT 1 FROM tokens) \
                     OR EXISTS (SELECT 1 FROM sensor_types) OR EXISTS (SELECT 1 FROM standards) \
                 OR EXISTS (SELECT 1 FROM customers) OR EXISTS (SELECT 1 FROM items))",
                    &[],
                )
                .await
                .map_err(errors::map)?;
            Ok(row.get(0))
        })
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

    async fn close(&self) {
        // What this replica's acts wrote, chained before it goes (another
        // replica's sealer, or the next start, would otherwise), once its
        // sealer has finished.
        self.sealer.stop().await;
        if let Ok(mut c) = self.client().await
            && let Err(e) = seal::seal_pending(&mut c).await
        {
            tracing::warn!(error = %e.chain(), "the audit trail was not sealed at shutdown");
        }
        self.cache.close();
        self.pool.close();
    }
}
