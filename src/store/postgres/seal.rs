//! The sealer: entries that acts wrote to `audit_pending` chained into the
//! audit trail (issue 48 item 2).
//!
//! Until version 15 every act took `audit`'s `EXCLUSIVE` lock to read the
//! head and append, and held it to its commit: every writing transaction
//! of every replica waited for the one before it to commit and flush, so a
//! fleet wrote one commit at a time. Now an act only inserts its entries
//! into `audit_pending` (`super::audit::append`), which waits for no one,
//! and the chain is advanced here, by one sealer at a time (the lock is
//! still `audit`'s, taken by sealers only), in one transaction that
//! deletes the pending entries it read and inserts them chained — so an
//! entry is either pending or sealed, never both, never neither.
//!
//! **Order.** The sealer takes every pending entry its statement sees, in
//! `id` order, after the head. An act's entries keep the act's order; an act
//! that began after another committed (it read that act's result: an
//! approval of a stored calibration, an amendment of an issued certificate)
//! holds greater ids (the identity's sequence caches no values per
//! session, so ids are handed out in the order inserts ask for them) and
//! is visible to a sealer whenever that one is, so it is sealed after it.
//! Two acts that overlapped are in the order the sealers found them
//! committed — by id among those found at once, so one numbered first but
//! committed after the other's seal comes after it.
//!
//! **When.** Each replica runs a sealer task: woken by its writer after
//! every committed batch of submissions and by every other act, sealing at
//! most once per [`EVERY`], and otherwise looking every [`POLL`] for
//! pending entries (any replica's: a replica that stopped leaves its last
//! entries to the others). A sealer that finds another replica's sealing
//! does not queue on the lock: it looks again after [`EVERY`] (what the
//! other did not see is still pending then). Every read of the trail — `GET
//! /v1/audit`, `accelcal audit verify` — seals first, under the lock, so it
//! sees every act committed before it began; a replica shutting down seals
//! what it can. `audit verify` reports entries still pending after its
//! check (acts committed while it ran).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use deadpool_postgres::{GenericClient, Pool, Transaction};
use time::OffsetDateTime;
use tokio::sync::Notify;

use super::errors::{map, pool};
use super::rows;
use crate::domain::audit::{Entry, Event};
use crate::store::StoreError;

/// How often a sealer looks for pending entries when no one woke it (any
/// replica's, left by one that stopped).
pub const POLL: Duration = Duration::from_secs(1);

/// A replica seals at most once per this interval: each seal is a
/// transaction and a WAL flush of its own, and sealing after every batch of
/// submissions doubled the flushes the writers wait behind
/// (BENCHMARKS.md, "Writes under the audit chain").
pub const EVERY: Duration = Duration::from_millis(50);

/// Pending entries sealed per statement.
const BATCH: i64 = 4096;

/// The chain's head: the last entry's sequence number and hash.
type Head = Option<(i64, String)>;

/// Takes the chain's lock in `tx`, until its end: the only lock a sealer
/// waits for, and no act takes it. A holder that stops talking mid-way (a
/// process frozen, a runtime blocked) is cut off by PostgreSQL after
/// [`STALLED`], so that it cannot keep every other sealer and reader of
/// the trail waiting.
pub async fn lock(tx: &Transaction<'_>) -> Result<(), StoreError> {
    tx.batch_execute(&locking("")).await.map_err(map)
}

/// [`lock`] unless another holds it (a replica's sealer sealing): `false`
/// then, and `tx` is aborted.
async fn try_lock(tx: &Transaction<'_>) -> Result<bool, StoreError> {
    match tx.batch_execute(&locking(" NOWAIT")).await {
        Ok(()) => Ok(true),
        Err(e) if e.code() == Some(&tokio_postgres::error::SqlState::LOCK_NOT_AVAILABLE) => {
            Ok(false)
        }
        Err(e) => Err(map(e)),
    }
}

fn locking(nowait: &str) -> String {
    format!(
        "SET LOCAL idle_in_transaction_session_timeout = {}; \
         LOCK TABLE audit IN EXCLUSIVE MODE{nowait}",
        STALLED.as_millis()
    )
}

/// How long a transaction holding the chain's lock may sit idle.
pub const STALLED: Duration = Duration::from_secs(10);

/// The chain's head as `tx` sees it (after [`lock`]: as it stands).
pub async fn head(tx: &Transaction<'_>) -> Result<Head, StoreError> {
    let last = tx
        .query_opt("SELECT seq, hash FROM audit ORDER BY seq DESC LIMIT 1", &[])
        .await
        .map_err(map)?;
    last.map(|r| Ok((rows::get(&r, "seq")?, rows::get(&r, "hash")?)))
        .transpose()
}

/// Chains `events`, in order, after `head` (under [`lock`]), and returns
/// the new head.
pub async fn chain(
    tx: &Transaction<'_>,
    head: Head,
    events: Vec<Event>,
) -> Result<Head, StoreError> {
    let mut head = head;
    if events.is_empty() {
        return Ok(head);
    }
    let mut entries = Vec::with_capacity(events.len());
    for event in events {
        let e = Entry::chain(head.as_ref().map(|(s, h)| (*s, h.as_str())), event);
        head = Some((e.seq, e.hash.clone()));
        entries.push(e);
    }
    let insert = tx
        .prepare_cached(
            "INSERT INTO audit (seq, at, token_id, role, holder, action, object, change, prev, hash) \
             SELECT * FROM unnest($1::int8[], $2::timestamptz[], $3::text[], $4::text[], \
             $5::text[], $6::text[], $7::text[], $8::text[], $9::text[], $10::text[])",
        )
        .await
        .map_err(map)?;
    let col = |f: fn(&Entry) -> &str| entries.iter().map(f).collect::<Vec<&str>>();
    let seqs: Vec<i64> = entries.iter().map(|e| e.seq).collect();
    let ats: Vec<OffsetDateTime> = entries.iter().map(|e| e.at.datetime()).collect();
    let holders: Vec<Option<&str>> = entries.iter().map(|e| e.actor.holder.as_deref()).collect();
    tx.execute(
        &insert,
        &[
            &seqs,
            &ats,
            &col(|e| &e.actor.token_id),
            &col(|e| &e.actor.role),
            &holders,
            &col(|e| &e.action),
            &col(|e| &e.object),
            &col(|e| &e.change),
            &col(|e| &e.prev),
            &col(|e| &e.hash),
        ],
    )
    .await
    .map_err(map)?;
    Ok(head)
}

/// Seals every pending entry `tx` sees (under [`lock`]), in `id` order,
/// and returns the new head and how many it sealed.
pub async fn seal_in(tx: &Transaction<'_>) -> Result<(Head, usize), StoreError> {
    let mut head = head(tx).await?;
    let take = tx
        .prepare_cached(
            "DELETE FROM audit_pending WHERE id IN \
             (SELECT id FROM audit_pending ORDER BY id LIMIT $1) \
             RETURNING id, at, token_id, role, holder, action, object, change",
        )
        .await
        .map_err(map)?;
    let mut sealed = 0;
    loop {
        let found = tx.query(&take, &[&BATCH]).await.map_err(map)?;
        let mut pending = Vec::with_capacity(found.len());
        for r in &found {
            let id: i64 = rows::get(r, "id")?;
            pending.push((id, rows::event(r)?));
        }
        // `RETURNING` promises no order.
        pending.sort_by_key(|(id, _)| *id);
        let n = pending.len();
        head = chain(tx, head, pending.into_iter().map(|(_, e)| e).collect()).await?;
        sealed += n;
        if (n as i64) < BATCH {
            return Ok((head, sealed));
        }
    }
}

/// Seals every pending entry committed before this call, in a transaction
/// of its own on `client`, queueing for the chain's lock ([`lock`]): a
/// reader of the trail, `audit verify`, shutdown. How many.
pub async fn seal(client: &mut deadpool_postgres::Object) -> Result<usize, StoreError> {
    let tx = client.transaction().await.map_err(map)?;
    lock(&tx).await?;
    sealed(tx).await
}

/// [`seal_in`] under the chain's lock `tx` holds, then the commit: how many
/// it sealed.
async fn sealed(tx: Transaction<'_>) -> Result<usize, StoreError> {
    let (_, n) = seal_in(&tx).await?;
    tx.commit().await.map_err(map)?;
    Ok(n)
}

/// Entries committed and not yet sealed.
pub async fn pending(client: &impl GenericClient) -> Result<i64, StoreError> {
    let r = client
        .query_one("SELECT count(*) FROM audit_pending", &[])
        .await
        .map_err(map)?;
    rows::get(&r, "count")
}

/// A replica's sealer task; it ends once [`stop`](Self::stop)ped or
/// dropped, after the seal in progress.
pub struct Sealer {
    wake: Arc<Notify>,
    sealed: Arc<tokio::sync::watch::Sender<u64>>,
    stopping: Arc<AtomicBool>,
    task: std::sync::Mutex<Option<tokio::task::JoinHandle<()>>>,
}

impl Sealer {
    /// Starts the task over `pool`, on the current tokio runtime.
    pub fn start(pool: Pool) -> Self {
        let wake = Arc::new(Notify::new());
        let sealed = Arc::new(tokio::sync::watch::Sender::new(0));
        let stopping = Arc::new(AtomicBool::new(false));
        let task = tokio::spawn(run(pool, wake.clone(), sealed.clone(), stopping.clone()));
        Sealer {
            wake,
            sealed,
            stopping,
            task: std::sync::Mutex::new(Some(task)),
        }
    }

    /// Stops the task and waits for the seal in progress to end (at
    /// shutdown, before the last seal and the pool's close).
    pub async fn stop(&self) {
        self.stopping.store(true, Ordering::Relaxed);
        self.wake.notify_one();
        let task = self.task.lock().ok().and_then(|mut t| t.take());
        if let Some(task) = task {
            let _ = task.await;
        }
    }

    /// Asks the task to seal now (after a commit that wrote entries).
    pub fn wake(&self) {
        self.wake.notify_one();
    }

    /// What wakes the task, for the writer.
    pub fn waker(&self) -> Arc<Notify> {
        self.wake.clone()
    }

    /// A receiver of the count of seals that chained entries: the trail
    /// grew ([`crate::store::Audit::trail_grew`]).
    pub fn sealed(&self) -> tokio::sync::watch::Receiver<u64> {
        self.sealed.subscribe()
    }
}

impl Drop for Sealer {
    fn drop(&mut self) {
        self.stopping.store(true, Ordering::Relaxed);
        self.wake.notify_one();
    }
}

async fn run(
    pool: Pool,
    wake: Arc<Notify>,
    sealed: Arc<tokio::sync::watch::Sender<u64>>,
    stopping: Arc<AtomicBool>,
) {
    let mut failing = false;
    let mut last = tokio::time::Instant::now();
    loop {
        tokio::select! {
            () = wake.notified() => {}
            () = tokio::time::sleep(POLL) => {}
        }
        if stopping.load(Ordering::Relaxed) {
            return;
        }
        tokio::time::sleep_until(last + EVERY).await;
        if stopping.load(Ordering::Relaxed) {
            return;
        }
        last = tokio::time::Instant::now();
        match once(&pool).await {
            Ok(Some(n)) => {
                failing = false;
                if n > 0 {
                    sealed.send_modify(|n| *n = n.wrapping_add(1));
                }
            }
            // Another replica's sealer is sealing; what it did not see is
            // looked at again after EVERY, rather than queued behind it.
            Ok(None) => {
                failing = false;
                wake.notify_one();
            }
            Err(e) if !failing => {
                failing = true;
                tracing::warn!(error = %e.chain(), "the audit sealer could not seal (retrying)");
            }
            Err(_) => {}
        }
    }
}

/// One look on a pooled connection: [`seal_pending`], except that it does
/// not wait for the chain's lock — `None` when another replica's sealer
/// holds it. Two sealers that queued on the lock sealed one after the
/// other, each a transaction and a WAL flush, the second mostly for the
/// few entries committed meanwhile (BENCHMARKS.md, "Student's quantile
/// remembered…": `Lock:relation` 26 % of the busy backends with two
/// replicas on one sensor).
async fn once(p: &Pool) -> Result<Option<usize>, StoreError> {
    let mut client = p.get().await.map_err(pool)?;
    if !any_pending(&client).await? {
        return Ok(Some(0));
    }
    let tx = client.transaction().await.map_err(map)?;
    if !try_lock(&tx).await? {
        return Ok(None);
    }
    sealed(tx).await.map(Some)
}

/// Whether anything committed is pending (see [`seal_pending`]).
async fn any_pending(client: &deadpool_postgres::Object) -> Result<bool, StoreError> {
    let any = client
        .query_opt("SELECT id FROM audit_pending ORDER BY id LIMIT 1", &[])
        .await
        .map_err(map)?;
    Ok(any.is_some())
}

/// [`seal`]s when anything committed is pending, without the lock when
/// nothing is: a reader of the trail does not queue behind the sealers for
/// nothing. (Entries a sealer is chaining right now are still pending to
/// this look until its commit, so they are waited for.) The look walks the
/// primary key, not the table: a queue's table is mostly dead rows between
/// two vacuums, which a scan of the heap would read every time.
pub async fn seal_pending(client: &mut deadpool_postgres::Object) -> Result<usize, StoreError> {
    if !any_pending(client).await? {
        return Ok(0);
    }
    seal(client).await
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_testkit::pg::TestDb;

    /// The sealer's look does not queue behind a holder of the chain's
    /// lock: it answers `None` at once and leaves the entry pending; once
    /// the lock is free the next look seals it.
    #[tokio::test]
    async fn a_sealer_does_not_wait_for_another() {
        let db = TestDb::create().await;
        crate::store::postgres::PostgresStore::open(&db.url)
            .await
            .unwrap();
        let pool = super::super::connect::pool(&db.url).unwrap();
        let holder = db.client().await;
        holder
            .batch_execute(
                "INSERT INTO audit_pending (at, token_id, role, action, object, change) \
                 VALUES (now(), 't', 'admin', 'token.create', 'tokens/t', '{}')",
            )
            .await
            .unwrap();
        holder
            .batch_execute("BEGIN; LOCK TABLE audit IN EXCLUSIVE MODE")
            .await
            .unwrap();
        let look = tokio::time::timeout(Duration::from_secs(5), once(&pool)).await;
        assert_eq!(look.expect("it waited for the lock").unwrap(), None);
        let client = pool.get().await.unwrap();
        assert_eq!(pending(&client).await.unwrap(), 1);
        holder.batch_execute("COMMIT").await.unwrap();
        assert_eq!(once(&pool).await.unwrap(), Some(1));
        assert_eq!(pending(&client).await.unwrap(), 0);
    }
}
