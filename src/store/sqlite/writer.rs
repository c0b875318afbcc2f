//! Group commit: one writer thread stores what many requests wrote, in one
//! transaction and one `fsync`.
//!
//! SQLite lets one connection write at a time, and with `synchronous=FULL`
//! every commit waits for the disk. Each request committing on its own thus
//! queues on the write lock (SQLite's busy handler sleeps and retries, which
//! is unfair: the tail grew past a second at 64 connections) and pays a
//! whole `fsync` for a few kilobytes. Here requests hand their writes to a
//! bounded queue; the writer takes everything waiting (up to [`MAX_BATCH`]),
//! runs each write in a savepoint of one `BEGIN IMMEDIATE` transaction,
//! commits once, and only then answers each request. So:
//!
//! * every answer still follows the durable commit of what it reports (a
//!   201 is never sent for a calibration that a crash could lose);
//! * a write that fails or decides to store nothing (a key completed by
//!   another request) rolls back its own savepoint, not its neighbours';
//! * if the commit itself fails, every write of the batch is told so and
//!   nothing of the batch is stored;
//! * when [`QUEUE`] writes are already waiting, a new one is refused at once
//!   with [`StoreError::Overloaded`] (503, `Retry-After: 1`) instead of
//!   adding unbounded latency and memory.
//!
//! With n writes waiting, a batch costs one `fsync` instead of n, so the
//! queue drains faster the longer it is: the throughput grows with load
//! instead of the latency. Kept because it pays: with batches of one, 64
//! connections stored 0.47× the submissions per second (`benches/load.rs`,
//! side by side).

use std::sync::Mutex;
use std::thread::JoinHandle;

use rusqlite::{Connection, TransactionBehavior};
use tokio::sync::{mpsc, oneshot};

use super::errors::map;
use super::pool::Pool;
use crate::store::StoreError;

/// Writes waiting for the writer at most; one more is refused.
pub const QUEUE: usize = 512;

/// Writes in one transaction at most.
pub const MAX_BATCH: usize = 256;

/// What a write asks of the writer: run in a savepoint, then hear how the
/// commit went.
trait Job: Send {
    /// Runs the write on the transaction's connection; returns whether its
    /// savepoint is to be kept, and how to answer once the commit is done.
    fn run(self: Box<Self>, conn: &Connection) -> Ran;
    /// Answers without running (the batch could not start).
    fn fail(self: Box<Self>, e: StoreError);
}

/// A write that ran, waiting for its batch's commit.
struct Ran {
    keep: bool,
    answer: Box<dyn FnOnce(Result<(), String>) + Send>,
}

/// One write: a closure and where its answer goes.
struct Write<T, F> {
    f: F,
    reply: oneshot::Sender<Result<T, StoreError>>,
}

impl<T, F> Job for Write<T, F>
where
    T: Send + 'static,
    F: FnOnce(&Connection) -> Result<(T, bool), StoreError> + Send,
{
    fn run(self: Box<Self>, conn: &Connection) -> Ran {
        let out = (self.f)(conn);
        let keep = matches!(out, Ok((_, true)));
        let reply = self.reply;
        Ran {
            keep,
            answer: Box::new(move |commit| {
                let answer = match (out, commit) {
                    (Err(e), _) => Err(e),
                    (Ok(_), Err(e)) => Err(StoreError::Unavailable(e.into())),
                    (Ok((t, _)), Ok(())) => Ok(t),
                };
                // The request may have gone (client away, timeout): its
                // write stands all the same.
                let _ = reply.send(answer);
            }),
        }
    }

    fn fail(self: Box<Self>, e: StoreError) {
        let _ = self.reply.send(Err(e));
    }
}

enum Msg {
    Job(Box<dyn Job>),
    Stop,
}

/// The queue and the thread that drains it.
pub struct Writer {
    /// When a batch last failed because the disk was full.
    pub full_at: std::sync::Arc<Mutex<Option<std::time::Instant>>>,
    /// Counts committed batches (each reader of the trail watches it).
    pub committed: std::sync::Arc<tokio::sync::watch::Sender<u64>>,
    queue: mpsc::Sender<Msg>,
    capacity: usize,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl Writer {
    /// Starts the writer thread over `pool`, refusing writes when
    /// `capacity` are waiting.
    pub fn start(pool: std::sync::Arc<Pool>, capacity: usize) -> Result<Self, StoreError> {
        let (queue, rx) = mpsc::channel(capacity);
        let full_at = std::sync::Arc::new(Mutex::new(None));
        let full = full_at.clone();
        let committed = std::sync::Arc::new(tokio::sync::watch::Sender::new(0));
        let done = committed.clone();
        let thread = std::thread::Builder::new()
            .name("accelcal-sqlite-writer".into())
            .spawn(move || drain(&pool, &full, &done, rx))
            .map_err(|e| StoreError::Unavailable(Box::new(e)))?;
        Ok(Writer {
            full_at,
            committed,
            queue,
            capacity,
            thread: Mutex::new(Some(thread)),
        })
    }

    /// Runs `f` in the next batch and answers after its commit. `f` returns
    /// its value and whether what it wrote is to be kept (false rolls its
    /// savepoint back; an error always does).
    pub async fn write<T, F>(&self, f: F) -> Result<T, StoreError>
    where
        T: Send + 'static,
        F: FnOnce(&Connection) -> Result<(T, bool), StoreError> + Send + 'static,
    {
        let (reply, answer) = oneshot::channel();
        let job: Box<dyn Job> = Box::new(Write { f, reply });
        self.queue.try_send(Msg::Job(job)).map_err(|e| match e {
            mpsc::error::TrySendError::Full(_) => StoreError::Overloaded(self.capacity),
            mpsc::error::TrySendError::Closed(_) => {
                StoreError::Unavailable("the database writer has stopped".into())
            }
        })?;
        answer
            .await
            .map_err(|_| StoreError::Unavailable("the database writer has stopped".into()))?
    }

    /// Stores what is queued, then stops the thread (at shutdown).
    pub fn stop(&self) {
        let Some(thread) = self.thread.lock().expect("writer lock").take() else {
            return;
        };
        // Waits for room in a full queue: every queued write is stored.
        if self.queue.blocking_send(Msg::Stop).is_ok() {
            let _ = thread.join();
        }
    }
}

/// The writer thread: batch, run, commit, answer, until told to stop.
fn drain(
    pool: &Pool,
    full: &Mutex<Option<std::time::Instant>>,
    committed: &tokio::sync::watch::Sender<u64>,
    mut rx: mpsc::Receiver<Msg>,
) {
    let mut stop = false;
    while !stop {
        let Some(first) = rx.blocking_recv() else {
            return;
        };
        let mut batch = Vec::new();
        let mut next = Some(first);
        while let Some(msg) = next.take() {
            match msg {
                Msg::Job(job) => batch.push(job),
                Msg::Stop => stop = true,
            }
            if !stop && batch.len() < MAX_BATCH {
                next = rx.try_recv().ok();
            }
        }
        if !batch.is_empty() {
            metrics::histogram!("accelcal_storage_write_batch_size").record(batch.len() as f64);
            match commit(pool, batch) {
                Ok(()) => committed.send_modify(|n| *n = n.wrapping_add(1)),
                Err(e) if super::errors::is_full(&e) => {
                    *full.lock().unwrap_or_else(|e| e.into_inner()) =
                        Some(std::time::Instant::now());
                }
                Err(_) => {}
            }
        }
    }
}

/// Runs one batch in one transaction; answers every write after the commit.
fn commit(pool: &Pool, batch: Vec<Box<dyn Job>>) -> Result<(), StoreError> {
    let mut p = match pool.checkout() {
        Ok(p) => p,
        Err(e) => {
            fail_all(batch, &e);
            return Err(e);
        }
    };
    let mut ran = Vec::with_capacity(batch.len());
    let mut jobs = batch.into_iter();
    let outcome = (|| {
        let mut tx = p
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)
            .map_err(map)?;
        for job in jobs.by_ref() {
            let sp = match tx.savepoint() {
                Ok(sp) => sp,
                Err(e) => {
                    job.fail(StoreError::Unavailable(
                        "the batch's transaction failed".into(),
                    ));
                    return Err(map(e));
                }
            };
            let r = job.run(&sp);
            // Keep: RELEASE; otherwise ROLLBACK TO and RELEASE.
            let settled = if r.keep { sp.commit() } else { sp.finish() };
            ran.push(r);
            settled.map_err(map)?;
            // Some errors (I/O, full disk) make SQLite roll the whole
            // transaction back by itself; what follows must not run, nor
            // commit, outside it.
            if tx.is_autocommit() {
                return Err(StoreError::Unavailable(
                    "the database rolled the batch's transaction back".into(),
                ));
            }
        }
        // A file replaced or removed meanwhile: the batch would commit
        // into the old, unlinked file and be lost with it.
        pool.check()?;
        tx.commit().map_err(map)
    })();
    // A transaction that did not commit was rolled back when dropped.
    let committed = outcome.as_ref().map(|_| ()).map_err(|e| e.chain());
    for r in ran {
        (r.answer)(committed.clone());
    }
    for job in jobs {
        job.fail(StoreError::Unavailable(
            "the batch's transaction failed".into(),
        ));
    }
    match outcome {
        Ok(()) => {
            pool.checkin(p);
            Ok(())
        }
        Err(e) => {
            tracing::warn!(error = %e.chain(), "a batch of writes did not commit");
            Err(e)
        }
    }
}

fn fail_all(batch: Vec<Box<dyn Job>>, e: &StoreError) {
    tracing::warn!(error = %e.chain(), "a batch of writes could not start");
    for job in batch {
        job.fail(StoreError::Unavailable(e.chain().into()));
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::time::Duration;

    use rusqlite::Connection;

    use super::*;

    fn setup(capacity: usize) -> (tempfile::TempDir, Arc<Pool>, Writer) {
        let dir = tempfile::tempdir().unwrap();
        let pool = Arc::new(Pool::create(dir.path().join("w.db")).unwrap());
        let c = pool.checkout().unwrap();
        c.conn.execute_batch("CREATE TABLE t (x INTEGER)").unwrap();
        pool.checkin(c);
        let writer = Writer::start(pool.clone(), capacity).unwrap();
        (dir, pool, writer)
    }

    /// Starts a write of `x` that holds the writer, once it has started,
    /// until the returned sender is used.
    fn hold(
        writer: &Arc<Writer>,
        x: i64,
    ) -> (
        tokio::task::JoinHandle<Result<i64, StoreError>>,
        std::sync::mpsc::Sender<()>,
    ) {
        let (started, wait) = std::sync::mpsc::channel();
        let (release, held) = std::sync::mpsc::channel::<()>();
        let w = writer.clone();
        let first = tokio::spawn(async move {
            w.write(move |c| {
                started.send(()).unwrap();
                held.recv().unwrap();
                insert(x)(c)
            })
            .await
        });
        wait.recv().unwrap();
        (first, release)
    }

    /// Waits (at most 5 s) until `n` writes wait in the queue.
    async fn until_queued(writer: &Writer, n: usize) {
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while writer.queue.capacity() > writer.queue.max_capacity() - n {
            assert!(std::time::Instant::now() < deadline, "write not queued");
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
    }

    fn rows(path: &std::path::Path) -> Vec<i64> {
        let c = Connection::open(path).unwrap();
        let mut st = c.prepare("SELECT x FROM t ORDER BY x").unwrap();
        st.query_map([], |r| r.get(0))
            .unwrap()
            .map(|r| r.unwrap())
            .collect()
    }

    fn insert(x: i64) -> impl FnOnce(&Connection) -> Result<(i64, bool), StoreError> {
        move |c| {
            c.execute("INSERT INTO t VALUES (?1)", [x]).map_err(map)?;
            Ok((x, true))
        }
    }

    /// Many writes at once share a batch; one that fails and one that
    /// declines to keep its rows roll back only themselves.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn each_write_of_a_batch_stands_or_falls_alone() {
        let (dir, _pool, writer) = setup(QUEUE);
        let writer = Arc::new(writer);
        let mut tasks = Vec::new();
        for x in 0..40 {
            let w = writer.clone();
            tasks.push(tokio::spawn(async move {
                match x {
                    13 => {
                        w.write(|c| {
                            c.execute("INSERT INTO t VALUES (13)", []).map_err(map)?;
                            Err::<(i64, bool), _>(StoreError::Refused("thirteen".into()))
                        })
                        .await
                    }
                    17 => {
                        w.write(|c| {
                            c.execute("INSERT INTO t VALUES (17)", []).map_err(map)?;
                            Ok((17, false))
                        })
                        .await
                    }
                    x => w.write(insert(x)).await,
                }
            }));
        }
        for (x, t) in tasks.into_iter().enumerate() {
            let got = t.await.unwrap();
            match x {
                13 => assert!(matches!(got, Err(StoreError::Refused(_)))),
                x => assert_eq!(got.unwrap(), x as i64),
            }
        }
        let expected: Vec<i64> = (0..40).filter(|x| *x != 13 && *x != 17).collect();
        assert_eq!(rows(&dir.path().join("w.db")), expected);
        tokio::task::spawn_blocking(move || writer.stop())
            .await
            .unwrap();
    }

    /// Every answer follows the commit: whoever hears "stored" can read it
    /// from another connection, even when a slow write later in the same
    /// batch holds the transaction open.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn answers_wait_for_the_commit_of_their_batch() {
        let (dir, _pool, writer) = setup(QUEUE);
        let writer = Arc::new(writer);
        // Hold the writer with a slow write so the next ones queue and
        // then share one batch, whose last write is slow too.
        let (first, release) = hold(&writer, 100);
        let w = writer.clone();
        let fast = tokio::spawn(async move { w.write(insert(1)).await });
        until_queued(&writer, 1).await;
        let w = writer.clone();
        let slow = tokio::spawn(async move {
            w.write(move |c| {
                std::thread::sleep(Duration::from_millis(300));
                insert(2)(c)
            })
            .await
        });
        until_queued(&writer, 2).await;
        release.send(()).unwrap();
        assert_eq!(fast.await.unwrap().unwrap(), 1);
        // Heard at once on the answer: the slow write of the same batch
        // must have committed too, or the answer came before the commit.
        assert_eq!(rows(&dir.path().join("w.db")), vec![1, 2, 100]);
        assert_eq!(slow.await.unwrap().unwrap(), 2);
        assert_eq!(first.await.unwrap().unwrap(), 100);
        tokio::task::spawn_blocking(move || writer.stop())
            .await
            .unwrap();
    }

    /// A full queue refuses at once (503 upstream), and what was queued is
    /// still stored once the database frees up.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_full_queue_refuses_instead_of_waiting() {
        let (dir, _pool, writer) = setup(2);
        let writer = Arc::new(writer);
        // Another connection holds the write lock: the writer's batch
        // waits for it (busy timeout) with its first write taken.
        let blocker = Connection::open(dir.path().join("w.db")).unwrap();
        blocker.execute_batch("BEGIN IMMEDIATE").unwrap();
        // Writes are sent one by one until the queue is full: the writer
        // takes the first ones into its batch (how many depends on the
        // scheduler), then waits for the lock and takes no more.
        let mut queued = Vec::new();
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while writer.queue.capacity() > 0 {
            assert!(std::time::Instant::now() < deadline, "queue never filled");
            let x = queued.len() as i64 + 1;
            let w = writer.clone();
            queued.push(tokio::spawn(async move { w.write(insert(x)).await }));
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        match writer.write(insert(1000)).await {
            Err(StoreError::Overloaded(2)) => {}
            other => panic!("expected Overloaded(2), got {other:?}"),
        }
        blocker.execute_batch("COMMIT").unwrap();
        let sent: Vec<i64> = (1..=queued.len() as i64).collect();
        for (t, x) in queued.into_iter().zip(sent.iter()) {
            assert_eq!(t.await.unwrap().unwrap(), *x);
        }
        assert!(sent.len() >= 3, "{} writes filled a queue of 2", sent.len());
        assert_eq!(rows(&dir.path().join("w.db")), sent);
        tokio::task::spawn_blocking(move || writer.stop())
            .await
            .unwrap();
    }

    /// Stopping stores what is queued first; a write after that is told
    /// the writer has stopped.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn stop_stores_what_is_queued() {
        let (dir, _pool, writer) = setup(QUEUE);
        let writer = Arc::new(writer);
        // The writer is held by a first write until 7 is surely queued.
        let (first, release) = hold(&writer, 6);
        let w = writer.clone();
        let queued = tokio::spawn(async move { w.write(insert(7)).await });
        until_queued(&writer, 1).await;
        let w = writer.clone();
        let stopping = tokio::task::spawn_blocking(move || w.stop());
        release.send(()).unwrap();
        stopping.await.unwrap();
        assert_eq!(first.await.unwrap().unwrap(), 6);
        assert_eq!(queued.await.unwrap().unwrap(), 7);
        assert_eq!(rows(&dir.path().join("w.db")), vec![6, 7]);
        assert!(matches!(
            writer.write(insert(8)).await,
            Err(StoreError::Unavailable(_))
        ));
    }
}
