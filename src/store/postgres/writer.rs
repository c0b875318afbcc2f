//! Group commit for PostgreSQL: one task per replica stores the
//! calibrations that many requests submitted, in one transaction.
//!
//! Each submission committing on its own costs PostgreSQL a transaction
//! start and end, a commit record and a WAL flush, and costs accelcal a
//! pooled connection for the time of four round trips; at 64 connections
//! submissions cost PostgreSQL most of its CPU, spread thin over sixteen
//! backends. Kept because it pays: with batches of one, 64 connections
//! stored 0.11× the submissions per second (`benches/load.rs`, side by
//! side). Here requests hand their calibrations to a
//! bounded queue; the writer takes everything waiting (up to
//! [`MAX_BATCH`]), writes them with [`batch::write`] — four statements for
//! the whole batch, not two to four per calibration — in one transaction on
//! one connection, commits once, and only then answers each
//! request. So:
//!
//! * every answer still follows the durable commit of what it reports
//!   (`synchronous_commit=on` on every connection);
//! * a batch is ordered by sensor, and its sensors are upserted in that
//!   order (one `unnest` of a sorted array, scanned in order), so two
//!   replicas' batches take sensors' row locks in one order and do not
//!   deadlock on them (a deadlock PostgreSQL still detects — two batches completing the same two
//!   idempotency keys at once — fails a statement, and is handled as the
//!   next point says);
//! * a write that fails (a constraint) aborts PostgreSQL's transaction, so
//!   the batch is rolled back and each of its writes is then stored in a
//!   transaction of its own — the failing one fails alone, exactly as it
//!   would have without batching; so does a key completed concurrently by
//!   another replica, or named twice in one batch
//!   ([`batch::Outcome::Raced`]);
//! * if the commit itself fails, every write of the batch is told so
//!   (503): nothing of it is acknowledged;
//! * when [`QUEUE`] writes are already waiting, a new one is refused at once
//!   with [`StoreError::Overloaded`] (503, `Retry-After: 1`);
//! * just before a batch commits, the sensors it changed are recorded as
//!   echoes ([`Echoes`]): the cache's listener then knows that their
//!   notifications are this replica's own, already applied.
//!
//! A batch holds at most 64 writes (SQLite's writer takes 256): a longer
//! transaction would hold its sensors' row locks longer against other
//! replicas. No savepoints are used, so a batch costs PostgreSQL no
//! subtransactions.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use deadpool_postgres::{Object, Pool};
use tokio::sync::{Notify, mpsc, oneshot};

use super::batch::{self, Outcome};
use super::calibrations::{self, Row};
use super::errors;
use super::listen::Echoes;
use crate::store::{IdempotencyKey, SensorRow, StoreError, Stored};

/// Writes waiting for the writer at most; one more is refused.
pub const QUEUE: usize = 512;

/// Writes in one transaction at most.
pub const MAX_BATCH: usize = 64;

/// One calibration waiting to be written, and where its answer goes.
struct Pending {
    row: Row,
    key: Option<IdempotencyKey>,
    reply: oneshot::Sender<Result<(Stored, Option<SensorRow>), StoreError>>,
}

impl Pending {
    fn answer(self, out: Result<(Stored, Option<SensorRow>), StoreError>) {
        // The request may have gone (client away, timeout): its write
        // stands all the same.
        let _ = self.reply.send(out);
    }
}

/// How many batches and writes the writer has committed (for tests and
/// diagnostics: whether writes are in fact grouped).
#[derive(Debug, Default)]
pub struct Counts {
    batches: AtomicU64,
    writes: AtomicU64,
}

impl Counts {
    /// `(batches, writes)` committed so far by batch transactions.
    pub fn get(&self) -> (u64, u64) {
        (
            self.batches.load(Ordering::Relaxed),
            self.writes.load(Ordering::Relaxed),
        )
    }
}

/// The queue, and the task that drains it.
pub struct Writer {
    queue: mpsc::Sender<Pending>,
    capacity: usize,
    counts: Arc<Counts>,
}

impl Writer {
    /// Starts the writer task over `pool` (on the current tokio runtime),
    /// refusing writes when `capacity` are waiting. The task ends when the
    /// writer is dropped and its queue is empty. With `echoes`, each batch
    /// records there what its commit will notify; after each batch it wakes
    /// `sealer` (its audit entries are pending: super::seal).
    pub fn start(
        pool: Pool,
        capacity: usize,
        echoes: Option<Arc<Echoes>>,
        sealer: Arc<Notify>,
    ) -> Self {
        let (queue, rx) = mpsc::channel(capacity);
        let counts = Arc::new(Counts::default());
        tokio::spawn(drain(pool, rx, counts.clone(), echoes, sealer));
        Writer {
            queue,
            capacity,
            counts,
        }
    }

    /// Stores `row` (and completes `key`) in the next batch; answers after
    /// its commit, with its sensor's row as the batch left it when it was
    /// stored.
    pub async fn insert(
        &self,
        row: Row,
        key: Option<IdempotencyKey>,
    ) -> Result<(Stored, Option<SensorRow>), StoreError> {
        let (reply, answer) = oneshot::channel();
        let pending = Pending { row, key, reply };
        self.queue.try_send(pending).map_err(|e| match e {
            mpsc::error::TrySendError::Full(_) => StoreError::Overloaded(self.capacity),
            mpsc::error::TrySendError::Closed(_) => stopped(),
        })?;
        answer.await.map_err(|_| stopped())?
    }

    /// Writes waiting in the queue now.
    pub fn queued(&self) -> usize {
        self.queue.max_capacity() - self.queue.capacity()
    }

    /// What the writer has committed in batches.
    pub fn counts(&self) -> &Counts {
        &self.counts
    }
}

fn stopped() -> StoreError {
    StoreError::Unavailable("the database writer has stopped".into())
}

/// The writer task: batch, write, commit, answer, until the queue closes.
async fn drain(
    pool: Pool,
    mut rx: mpsc::Receiver<Pending>,
    counts: Arc<Counts>,
    echoes: Option<Arc<Echoes>>,
    sealer: Arc<Notify>,
) {
    while let Some(first) = rx.recv().await {
        let mut batch = vec![first];
        while batch.len() < MAX_BATCH {
            match rx.try_recv() {
                Ok(p) => batch.push(p),
                Err(_) => break,
            }
        }
        metrics::histogram!("accelcal_storage_write_batch_size").record(batch.len() as f64);
        commit(&pool, batch, &counts, echoes.as_deref()).await;
        // Its `calibration.submitted` entries, chained (super::seal).
        sealer.notify_one();
    }
}

/// Why a batch's transaction did not commit.
enum Failed {
    /// A statement failed (its error, if it was a write's) or a key raced:
    /// the transaction was rolled back, nothing of it is stored, and each
    /// write may be tried alone.
    Write(Option<StoreError>),
    /// The commit failed: the outcome is unknown to accelcal.
    Commit(StoreError),
}

/// Stores one batch: in one transaction, or, when a write of it fails, each
/// write in a transaction of its own.
async fn commit(pool: &Pool, mut batch: Vec<Pending>, counts: &Counts, echoes: Option<&Echoes>) {
    batch.sort_by(|a, b| a.row.sensor_id().cmp(b.row.sensor_id()));
    let mut client = match pool.get().await {
        Ok(c) => c,
        Err(e) => {
            let e = errors::pool(e);
            tracing::warn!(error = %e.chain(), "a batch of writes could not start");
            for p in batch {
                p.answer(Err(StoreError::Unavailable(e.chain().into())));
            }
            return;
        }
    };
    match together(&mut client, &batch, echoes).await {
        Ok(stored) => {
            counts.batches.fetch_add(1, Ordering::Relaxed);
            counts
                .writes
                .fetch_add(batch.len() as u64, Ordering::Relaxed);
            for (p, s) in batch.into_iter().zip(stored) {
                p.answer(Ok(s));
            }
        }
        Err(Failed::Commit(e)) => {
            tracing::warn!(error = %e.chain(), "a batch of writes did not commit");
            for p in batch {
                p.answer(Err(StoreError::Unavailable(e.chain().into())));
            }
        }
        Err(Failed::Write(Some(e))) if batch.len() == 1 => {
            // Alone already: its own error is the answer.
            if let Some(p) = batch.pop() {
                p.answer(Err(e));
            }
        }
        Err(Failed::Write(_)) => {
            for p in batch {
                let out = calibrations::insert(&mut client, &p.row, p.key.as_ref()).await;
                p.answer(out);
            }
        }
    }
}

/// Writes every calibration of `batch` in one transaction and commits it;
/// records in `echoes` what the commit will notify, just before it.
async fn together(
    client: &mut Object,
    batch: &[Pending],
    echoes: Option<&Echoes>,
) -> Result<Vec<(Stored, Option<SensorRow>)>, Failed> {
    let tx = client
        .transaction()
        .await
        .map_err(|e| Failed::Write(Some(errors::map(e))))?;
    let writes: Vec<_> = batch.iter().map(|p| (&p.row, p.key.as_ref())).collect();
    // Returning early drops `tx`, which rolls the batch back.
    let (stored, changed) = match batch::write(&tx, &writes).await {
        Ok(Outcome::Stored(stored, changed)) => (stored, changed),
        Ok(Outcome::Raced) => return Err(Failed::Write(None)),
        Err(e) => return Err(Failed::Write(Some(e))),
    };
    let echo = echoes.zip(changed.as_ref());
    if let Some((e, c)) = echo {
        e.expect(c.pid, &c.sensors);
    }
    if let Err(err) = tx.commit().await {
        if let Some((e, c)) = echo {
            e.forget(c.pid, &c.sensors);
        }
        return Err(Failed::Commit(errors::map(err)));
    }
    Ok(stored)
}
