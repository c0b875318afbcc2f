//! A small pool of SQLite connections, each checked against the database
//! file it opened.
//!
//! A connection that reported an error is dropped rather than reused, and
//! every checkout checks that the file at the path is still the one the
//! pool was created on: a missing file is an outage until it is put back,
//! and another file moved over it (a backup restored) is refused until the
//! service restarts — a running service must not pair the new file with the
//! old one's WAL. (r2d2 and deadpool pool connections, but neither can tell
//! that the file behind one was replaced.)

use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::Duration;

use rusqlite::config::DbConfig;
use rusqlite::{Connection, OpenFlags};

use super::errors::map;
use super::migrations::migrate;
use crate::store::StoreError;

/// SQLite's `unix-excl` VFS: the first read takes a lock on the file that
/// no other process can share while this one has it open, and the WAL's
/// index lives in this process's heap instead of a memory-mapped `-shm`
/// file. So a second server (or any other program) cannot open a file one
/// serves — each would keep its own caches — and no page of a mapped file
/// can vanish under a write (a `-shm` made unwritable or truncated behind
/// SQLite's back is a SIGBUS). Connections of this process share the file
/// as usual.
const VFS: &std::ffi::CStr = c"unix-excl";

/// How long a statement waits for a lock held by another connection.
const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

/// Reads that may run at once, each on a connection of its own (more wait:
/// opening a connection parses the whole schema, so a pool that opened one
/// per extra concurrent read and dropped it after spent its time there).
pub const READERS: usize = 8;

/// Idle connections kept for reuse: one per reader and the writer's.
const POOL_SIZE: usize = READERS + 1;

/// Identity of the database file a connection opened (device, inode).
type FileId = (u64, u64);

/// A pooled connection.
pub struct Pooled {
    /// The connection.
    pub conn: Connection,
}

/// The pool.
pub struct Pool {
    path: PathBuf,
    /// The file the pool serves: the one at `path` when it was created.
    origin: FileId,
    idle: Mutex<Vec<Pooled>>,
    /// Connections opened so far.
    opened: AtomicUsize,
    /// When the pool was created, and how long after it the file was last
    /// found to be the one served, in microseconds ([`Pool::check_recent`]).
    created: std::time::Instant,
    last_good_us: AtomicU64,
}

/// How long a good check of the file stands for answers served from memory
/// ([`Pool::check_recent`]); it buys 11–20 % of the cached routes'
/// throughput at 64 connections, a `stat` per answer costing that much.
pub const RECHECK: std::time::Duration = std::time::Duration::from_millis(50);

fn file_id(path: &Path) -> Result<FileId, StoreError> {
    let meta = std::fs::metadata(path).map_err(|e| {
        StoreError::Unavailable(format!("database file {}: {e}", path.display()).into())
    })?;
    Ok((meta.dev(), meta.ino()))
}

/// The error once the file at the path is another file than the one served.
fn replaced(path: &Path) -> StoreError {
    StoreError::Unavailable(
        format!(
            "the database file {} was replaced while the service was running; restart \
             accelcal to serve the new file (a running service never switches files: \
             its WAL would be paired with the wrong database)",
            path.display()
        )
        .into(),
    )
}

impl Pool {
    /// A pool for the database at `path`, creating the file (readable by its
    /// owner only: it holds token hashes and every submission) if there is
    /// none. Only this first open may create it: later, a missing file is an
    /// outage to report, not an empty database to start afresh.
    pub fn create(path: PathBuf) -> Result<Self, StoreError> {
        if !path.exists() {
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .mode(0o600)
                .open(&path)
                .map_err(|e| {
                    StoreError::Unavailable(format!("creating {}: {e}", path.display()).into())
                })?;
        }
        let origin = file_id(&path)?;
        Ok(Pool {
            path,
            origin,
            idle: Mutex::new(Vec::new()),
            opened: AtomicUsize::new(0),
            created: std::time::Instant::now(),
            last_good_us: AtomicU64::new(0),
        })
    }

    /// The database file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Opens a new connection: WAL journal (SQLite gives the `-wal` and
    /// `-shm` files the database file's permissions), `synchronous=FULL`,
    /// foreign keys on, migrated.
    fn connect(&self) -> Result<Pooled, StoreError> {
        let flags = OpenFlags::SQLITE_OPEN_READ_WRITE
            | OpenFlags::SQLITE_OPEN_NO_MUTEX
            | OpenFlags::SQLITE_OPEN_URI;
        let mut conn = Connection::open_with_flags_and_vfs(&self.path, flags, VFS).map_err(map)?;
        conn.busy_timeout(BUSY_TIMEOUT).map_err(map)?;
        conn.pragma_update_and_check(None, "journal_mode", "WAL", |r| r.get::<_, String>(0))
            .map_err(map)?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(map)?;
        conn.pragma_update(None, "foreign_keys", "ON")
            .map_err(map)?;
        // Query-planner stability: a plan does not depend on the values
        // bound, so a cached statement runs as prepared. Without it, a
        // statement whose plan could depend on a bound value is prepared
        // again on every run after its bindings are cleared — under load,
        // a quarter of the server's time was that parsing.
        conn.set_db_config(DbConfig::SQLITE_DBCONFIG_ENABLE_QPSG, true)
            .map_err(map)?;
        migrate(&mut conn).map_err(map)?;
        self.opened.fetch_add(1, Ordering::Relaxed);
        Ok(Pooled { conn })
    }

    /// A connection to the database file: 503 while the file is missing
    /// (it may be put back) or is another file than the one served.
    pub fn checkout(&self) -> Result<Pooled, StoreError> {
        self.check()?;
        let pooled = self.idle.lock().expect("pool lock").pop();
        match pooled {
            Some(p) => Ok(p),
            None => self.connect(),
        }
    }

    /// Whether the file at the path is the one served (see [`replaced`]).
    pub fn check(&self) -> Result<(), StoreError> {
        if file_id(&self.path)? == self.origin {
            Ok(())
        } else {
            Err(replaced(&self.path))
        }
    }

    /// [`Pool::check`] for answers served from memory: a good check stands
    /// for [`RECHECK`], so a replaced file is refused within that time
    /// (writes, and reads that reach the file, check every time). A bad one
    /// stands for nothing: the next call checks again.
    pub fn check_recent(&self) -> Result<(), StoreError> {
        let now_us = self.created.elapsed().as_micros() as u64;
        let last = self.last_good_us.load(Ordering::Relaxed);
        if last != 0 && now_us.saturating_sub(last) < RECHECK.as_micros() as u64 {
            return Ok(());
        }
        self.check()?;
        self.last_good_us.store(now_us.max(1), Ordering::Relaxed);
        Ok(())
    }

    /// Returns a connection that worked to the pool.
    pub fn checkin(&self, p: Pooled) {
        let mut idle = self.idle.lock().expect("pool lock");
        if idle.len() < POOL_SIZE {
            idle.push(p);
        }
    }

    /// Connections opened since the pool was created.
    pub fn opened(&self) -> usize {
        self.opened.load(Ordering::Relaxed)
    }

    /// Takes every idle connection (at shutdown).
    pub fn drain(&self) -> Vec<Pooled> {
        std::mem::take(&mut *self.idle.lock().expect("pool lock"))
    }
}

#[cfg(test)]
mod tests {
    use std::os::unix::fs::PermissionsExt;

    use rusqlite::OptionalExtension;

    use super::*;

    #[test]
    fn a_missing_file_is_not_recreated_after_the_first_open() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("gone.db");
        let pool = Pool::create(path.clone()).unwrap();
        pool.checkin(pool.checkout().unwrap());
        std::fs::remove_file(&path).unwrap();
        assert!(matches!(pool.checkout(), Err(StoreError::Unavailable(_))));
        assert!(!path.exists());
    }

    /// For answers from memory a good check stands for [`RECHECK`]; a bad
    /// one for nothing, and the same file back is served again.
    #[test]
    fn a_replaced_file_is_refused_within_the_recheck_interval() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("live.db");
        let pool = Pool::create(path.clone()).unwrap();
        assert!(pool.check_recent().is_ok());
        let aside = dir.path().join("aside.db");
        std::fs::rename(&path, &aside).unwrap();
        std::fs::write(&path, b"another file").unwrap();
        assert!(pool.check().is_err(), "the exact check sees it at once");
        std::thread::sleep(RECHECK + std::time::Duration::from_millis(10));
        for _ in 0..2 {
            assert!(matches!(
                pool.check_recent(),
                Err(StoreError::Unavailable(_))
            ));
        }
        std::fs::rename(&aside, &path).unwrap();
        assert!(pool.check_recent().is_ok());
    }

    /// The durability promise rests on these settings of every connection a
    /// commit can run on: a kill -9 test alone cannot tell `FULL` from `OFF`.
    #[test]
    fn every_pooled_connection_commits_durably() {
        let dir = tempfile::tempdir().unwrap();
        let pool = Pool::create(dir.path().join("durable.db")).unwrap();
        // Eight at once: the pool must open fresh connections for them.
        let held: Vec<Pooled> = (0..8).map(|_| pool.checkout().unwrap()).collect();
        for p in &held {
            let sync: i64 = p
                .conn
                .pragma_query_value(None, "synchronous", |r| r.get(0))
                .unwrap();
            let journal: String = p
                .conn
                .pragma_query_value(None, "journal_mode", |r| r.get(0))
                .unwrap();
            let fk: i64 = p
                .conn
                .pragma_query_value(None, "foreign_keys", |r| r.get(0))
                .unwrap();
            assert_eq!(sync, 2, "synchronous must be FULL (2)");
            assert_eq!(journal, "wal");
            assert_eq!(fk, 1);
        }
        for p in held {
            pool.checkin(p);
        }
        // And the ones handed out again from the pool.
        let again = pool.checkout().unwrap();
        let sync: i64 = again
            .conn
            .pragma_query_value(None, "synchronous", |r| r.get(0))
            .unwrap();
        assert_eq!(sync, 2);
    }

    /// A cached statement runs as prepared, whatever is bound to it: the
    /// history query's shape (two indexes could serve it) ran through the
    /// parser again on every run before the planner was made stable.
    #[test]
    fn cached_statements_are_not_prepared_again() {
        let dir = tempfile::tempdir().unwrap();
        let pool = Pool::create(dir.path().join("plans.db")).unwrap();
        let p = pool.checkout().unwrap();
        let sql = "SELECT c.id FROM calibrations c WHERE c.sensor_id = ?1 AND c.performed_at < ?2 \
                   ORDER BY c.performed_at DESC, c.id DESC LIMIT 1";
        for (sensor, before) in [
            ("A", "2026-01-01"),
            ("B", "2026-02-01"),
            ("A", "2026-03-01"),
        ] {
            let mut st = p.conn.prepare_cached(sql).unwrap();
            let found: Option<String> = st
                .query_row(rusqlite::params![sensor, before], |r| r.get(0))
                .optional()
                .unwrap();
            assert_eq!(found, None);
        }
        let st = p.conn.prepare_cached(sql).unwrap();
        assert_eq!(st.get_status(rusqlite::StatementStatus::Run), 3);
        assert_eq!(st.get_status(rusqlite::StatementStatus::RePrepare), 0);
    }

    #[test]
    fn the_database_and_its_wal_are_private_to_their_owner() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("private.db");
        let pool = Pool::create(path.clone()).unwrap();
        let c = pool.checkout().unwrap();
        c.conn
            .execute_batch("CREATE TABLE t (x); INSERT INTO t VALUES (1);")
            .unwrap();
        for file in [path.clone(), path.with_extension("db-wal")] {
            let mode = std::fs::metadata(&file).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o600, "{}", file.display());
        }
        // `unix-excl`: the WAL's index is in this process's heap.
        assert!(!path.with_extension("db-shm").exists());
    }

    /// Another process cannot open a file this one serves: a second
    /// `accelcal` (here: a child `sqlite3`-like open through Python's
    /// sqlite3, a separate process) finds it locked.
    #[test]
    fn another_process_cannot_read_a_served_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("excl.db");
        let pool = Pool::create(path.clone()).unwrap();
        let c = pool.checkout().unwrap();
        c.conn
            .execute_batch("CREATE TABLE t (x); INSERT INTO t VALUES (1);")
            .unwrap();
        pool.checkin(c);
        let out = std::process::Command::new("python3")
            .arg("-c")
            .arg(
                "import sqlite3, sys\n\
                 try:\n    sqlite3.connect(sys.argv[1], timeout=0.2).execute('SELECT * FROM t').fetchall(); print('read')\n\
                 except sqlite3.OperationalError as e:\n    print('refused:', e)",
            )
            .arg(&path)
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.starts_with("refused: database is locked"), "{said}");
    }
}
