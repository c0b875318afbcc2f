//! The SQLite engine: one file, WAL journal, `synchronous=FULL`.
//!
//! A commit returns only once the WAL is on stable storage, so an
//! acknowledged calibration survives a crash or power loss; a transaction
//! interrupted by a crash is rolled back on the next open. Submissions and
//! idempotency claims go through the [`writer`], which commits many in one
//! transaction (group commit); other calls run on tokio's blocking pool over
//! a small [`pool`] of connections. One file per
//! concern: [`calibrations`], [`sensors`], [`sensor_types`], [`standards`], [`tokens`], [`audit`],
//! [`sessions`], [`idempotency`];
//! [`rows`] decodes rows by column name, [`errors`] maps the driver's errors.

mod audit;
mod calibrations;
mod certificates;
mod customers;
mod definitions;
mod errors;
mod fitted;
mod holder;
mod holds;
mod idempotency;
mod migrations;
mod pool;
mod reviews;
mod rows;
mod sensor_types;
mod sensors;
mod sessions;
mod signatures;
mod standards;
mod tokens;
mod webhooks;
pub mod writer;

pub use self::pool::{READERS, RECHECK};

use std::path::{Path, PathBuf};
use std::sync::Arc;

use async_trait::async_trait;
use rusqlite::{Connection, OptionalExtension};

use self::pool::Pool;
use self::writer::Writer;
use super::cache::Cache;
use super::{Database, StoreError};

/// Free bytes the database's disk must have for the service to be ready,
/// by default: room for thousands of submissions and a checkpoint.
pub const MIN_FREE_BYTES: u64 = 64 * 1024 * 1024;

/// How long readiness fails after a write found the disk full (then it is
/// tried again, whatever `statvfs` says: quotas and reserved blocks are not
/// all visible to it).
pub const FULL_HOLD: std::time::Duration = std::time::Duration::from_secs(10);

/// 503 when the file system holding `path` has less than `min` bytes free
/// for unprivileged use.
fn room(path: &Path, min: u64) -> Result<(), StoreError> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let st = rustix::fs::statvfs(dir).map_err(|e| StoreError::Unavailable(Box::new(e)))?;
    let free = st.f_bavail.saturating_mul(st.f_frsize);
    if free < min {
        return Err(StoreError::Unavailable(
            format!(
                "only {} MiB free on the disk of {} (at least {} MiB are kept for work)",
                free / (1024 * 1024),
                path.display(),
                min.div_ceil(1024 * 1024)
            )
            .into(),
        ));
    }
    Ok(())
}

/// A SQLite-backed [`Store`](crate::store::Store).
#[derive(Clone)]
pub struct SqliteStore {
    /// Free bytes the disk must keep for readiness ([`MIN_FREE_BYTES`]).
    min_free: u64,
    pool: Arc<Pool>,
    writer: Arc<Writer>,
    /// One permit per reader connection ([`READERS`]).
    readers: Arc<tokio::sync::Semaphore>,
    /// Off unless [`cached`](Self::cached).
    cache: Arc<Cache>,
}

impl SqliteStore {
    /// Opens (creating if needed, mode 0600) the database at `path`,
    /// migrates it, and frees the idempotency leases a crash left behind.
    pub fn open(path: impl Into<PathBuf>) -> Result<Self, StoreError> {
        Self::open_with_queue(path, writer::QUEUE)
    }

    /// [`SqliteStore::open`], refusing writes with
    /// [`StoreError::Overloaded`] once `queue` are waiting for the writer.
    pub fn open_with_queue(path: impl Into<PathBuf>, queue: usize) -> Result<Self, StoreError> {
        let pool = Arc::new(Pool::create(path.into())?);
        let first = pool.checkout().map_err(|e| {
            if errors::is_busy(&e) {
                holder::in_use(pool.path())
            } else {
                e
            }
        })?;
        idempotency::free_leases(&first.conn)?;
        pool.checkin(first);
        let writer = Arc::new(Writer::start(pool.clone(), queue)?);
        Ok(SqliteStore {
            min_free: MIN_FREE_BYTES,
            pool,
            writer,
            readers: Arc::new(tokio::sync::Semaphore::new(pool::READERS)),
            cache: Arc::new(Cache::off()),
        })
    }

    /// The same store with a [`Cache`] of its own in front of its sensor
    /// and token reads, as it serves: one process serves a SQLite file, so
    /// every write passes through it. A clone made before shares the
    /// database but not the cache.
    pub fn cached(mut self) -> Self {
        self.cache = Arc::new(Cache::new(true));
        self
    }

    /// The cache (for tests).
    pub fn cache(&self) -> &Cache {
        &self.cache
    }

    /// The same store, ready only while its disk has `bytes` free.
    pub fn with_min_free(mut self, bytes: u64) -> Self {
        self.min_free = bytes;
        self
    }

    /// Connections opened so far (reads reuse at most [`READERS`]).
    pub fn connections_opened(&self) -> usize {
        self.pool.opened()
    }

    /// 503 when the file at the path is not the one served: what the cache
    /// answers runs this first, so nothing is answered from memory that the
    /// database no longer backs (a file removed, a backup moved over it). A
    /// good check stands for [`pool::RECHECK`].
    fn follow_the_file(&self) -> Result<(), StoreError> {
        self.pool.check_recent()
    }

    /// The database file.
    pub fn path(&self) -> &Path {
        self.pool.path()
    }

    /// Runs `f` on a pooled connection on the blocking pool, timed as
    /// `operation` (see [`crate::store::observe`]). A connection whose call
    /// failed is dropped, not returned.
    async fn run<T, F>(&self, operation: &'static str, f: F) -> Result<T, StoreError>
    where
        T: Send + 'static,
        F: FnOnce(&mut Connection) -> Result<T, StoreError> + Send + 'static,
    {
        let pool = self.pool.clone();
        let started = std::time::Instant::now();
        let permit = self.readers.clone().acquire_owned().await;
        let out = tokio::task::spawn_blocking(move || {
            // The semaphore is never closed; holding the permit keeps this
            // read within the pool's connections.
            let _permit = permit;
            let mut p = pool.checkout()?;
            let out = f(&mut p.conn);
            if out.is_ok() {
                pool.checkin(p);
            }
            out
        })
        .await
        .map_err(|e| StoreError::Unavailable(Box::new(e)))
        .and_then(|r| r);
        super::observe(operation, started, &out);
        out
    }
}

impl SqliteStore {
    /// Runs `f` in the writer's next batch (see [`writer`]), timed as
    /// `operation`; answers after the batch's durable commit.
    async fn write<T, F>(&self, operation: &'static str, f: F) -> Result<T, StoreError>
    where
        T: Send + 'static,
        F: FnOnce(&Connection) -> Result<(T, bool), StoreError> + Send + 'static,
    {
        let started = std::time::Instant::now();
        let out = self.writer.write(f).await;
        super::observe(operation, started, &out);
        out
    }
}

#[async_trait]
impl Database for SqliteStore {
    /// The database answers, and its disk has room for work: at least
    /// [`MIN_FREE_BYTES`] free (`statvfs`), and no write found it full in
    /// the last [`FULL_HOLD`].
    async fn ping(&self) -> Result<(), StoreError> {
        room(self.path(), self.min_free)?;
        if let Some(at) = *self
            .writer
            .full_at
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            && at.elapsed() < FULL_HOLD
        {
            return Err(StoreError::Unavailable(
                format!(
                    "a write found the disk of {} full {} s ago",
                    self.path().display(),
                    at.elapsed().as_secs()
                )
                .into(),
            ));
        }
        self.run("ping", |conn| {
            conn.query_row("SELECT count(*) FROM sensors", [], |r| r.get::<_, i64>(0))
                .map_err(errors::map)?;
            Ok(())
        })
        .await
    }

    async fn is_empty(&self) -> Result<bool, StoreError> {
        self.run("is_empty", |conn| {
            conn.query_row(
                "SELECT NOT (EXISTS (SELECT 1 FROM calibrations) OR EXISTS (SELECT 1 FROM tokens) \
                 OR EXISTS (SELECT 1 FROM sensor_types) OR EXISTS (SELECT 1 FROM standards) \
                 OR EXISTS (SELECT 1 FROM customers) OR EXISTS (SELECT 1 FROM items))",
                [],
                |r| r.get(0),
            )
            .map_err(errors::map)
        })
        .await
    }

    async fn import_in_progress(&self) -> Result<Option<String>, StoreError> {
        self.run("import_in_progress", |conn| {
            conn.query_row("SELECT description FROM import_in_progress", [], |r| {
                r.get(0)
            })
            .optional()
            .map_err(errors::map)
        })
        .await
    }

    async fn set_import_in_progress(&self, import: Option<String>) -> Result<(), StoreError> {
        self.run("set_import_in_progress", move |conn| {
            match import {
                Some(d) => conn.execute(
                    "INSERT INTO import_in_progress (singleton, description) VALUES (1, ?1) \
                     ON CONFLICT (singleton) DO UPDATE SET description = excluded.description",
                    [d],
                ),
                None => conn.execute("DELETE FROM import_in_progress", []),
            }
            .map(|_| ())
            .map_err(errors::map)
        })
        .await
    }

    /// `VACUUM INTO` a new file beside the database: one read transaction,
    /// so a consistent snapshot, while writes go on.
    async fn backup(&self) -> Result<Option<tempfile::NamedTempFile>, StoreError> {
        self.follow_the_file()?;
        let dir = self
            .path()
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf();
        self.run("backup", move |conn| {
            let file = tempfile::Builder::new()
                .prefix(".accelcal-backup-")
                .suffix(".db")
                .tempfile_in(&dir)
                .map_err(|e| StoreError::Unavailable(Box::new(e)))?;
            // VACUUM INTO needs a path with no database in it.
            std::fs::remove_file(file.path()).map_err(|e| StoreError::Unavailable(Box::new(e)))?;
            let target = file
                .path()
                .to_str()
                .ok_or_else(|| StoreError::Unavailable("a backup path that is not UTF-8".into()))?
                .to_owned();
            conn.execute("VACUUM INTO ?1", [target])
                .map_err(errors::map)?;
            Ok(Some(file))
        })
        .await
    }

    async fn close(&self) {
        self.cache.close();
        let pool = self.pool.clone();
        let writer = self.writer.clone();
        let _ = tokio::task::spawn_blocking(move || {
            writer.stop();
            let conns = pool.drain();
            if let Some(p) = conns.first() {
                // Fold the WAL back into the main file so a copy of the
                // database file alone is complete.
                if let Err(e) = p
                    .conn
                    .query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |_| Ok(()))
                {
                    tracing::warn!(error = %e, "WAL checkpoint at shutdown failed");
                }
            }
        })
        .await;
    }
}
