//! The database a process test runs on, and what must hold in it whatever
//! happened to the processes.

use rusqlite::Connection;

/// The database a crash test runs on.
pub enum Db {
    /// A SQLite file in this directory.
    Sqlite(tempfile::TempDir),
    /// A PostgreSQL database of its own.
    Postgres(accelcal_testkit::pg::TestDb),
}

impl Db {
    /// Its URL (a path for SQLite).
    pub fn url(&self) -> String {
        match self {
            Db::Sqlite(dir) => dir.path().join("crash.db").to_str().unwrap().to_owned(),
            Db::Postgres(db) => db.url.clone(),
        }
    }

    /// One number from a query that is the same on both engines.
    pub async fn number(&self, sql: &str) -> i64 {
        match self {
            Db::Sqlite(_) => Connection::open(self.url())
                .unwrap()
                .query_row(sql, [], |r| r.get(0))
                .unwrap(),
            Db::Postgres(db) => db.client().await.query_one(sql, &[]).await.unwrap().get(0),
        }
    }

    /// The database's own integrity check, and what must hold across tables.
    ///
    /// Every figure comes from one statement, so one snapshot: a killed
    /// process's PostgreSQL backends may still be committing what it sent
    /// while this runs, and each commit is atomic, so the invariants hold in
    /// every snapshot — but counts taken by separate statements could
    /// straddle a commit.
    pub async fn check(&self) {
        if let Db::Sqlite(_) = self {
            let ok: String = Connection::open(self.url())
                .unwrap()
                .query_row("PRAGMA integrity_check", [], |r| r.get(0))
                .unwrap();
            assert_eq!(ok, "ok");
        }
        let figures = [
            "SELECT count(*) FROM calibrations",
            "SELECT CAST(coalesce(sum(calibration_count), 0) AS bigint) FROM sensors",
            "SELECT count(*) FROM sensors s WHERE NOT EXISTS \
             (SELECT 1 FROM calibrations c WHERE c.id = s.latest_calibration_id AND c.sensor_id = s.sensor_id)",
            "SELECT count(*) FROM calibrations WHERE length(result) = 0 OR length(submission) = 0",
            "SELECT count(*) FROM idempotency_keys k WHERE k.calibration_id IS NOT NULL AND NOT EXISTS \
             (SELECT 1 FROM calibrations c WHERE c.id = k.calibration_id)",
            "SELECT count(*) FROM idempotency_keys WHERE calibration_id IS NOT NULL",
        ];
        let one_statement = format!(
            "SELECT CAST(({}) AS text)",
            figures
                .map(|f| format!("CAST(({f}) AS text)"))
                .join(") || ',' || (")
        );
        let row = self.text(&one_statement).await;
        let n: Vec<i64> = row.split(',').map(|x| x.parse().unwrap()).collect();
        let [
            calibrations,
            counted,
            orphans,
            incomplete,
            dangling,
            per_key,
        ] = n[..]
        else {
            panic!("six figures expected, got {row}");
        };
        assert_eq!(
            calibrations, counted,
            "sensor counters disagree with the calibrations"
        );
        assert_eq!(orphans, 0, "a sensor names a missing latest calibration");
        assert_eq!(incomplete, 0, "a calibration is half-written");
        assert_eq!(
            dangling, 0,
            "an idempotency key names a missing calibration"
        );
        assert_eq!(
            per_key, calibrations,
            "every calibration here was stored under its own key"
        );
    }

    /// One text from a query that is the same on both engines.
    async fn text(&self, sql: &str) -> String {
        match self {
            Db::Sqlite(_) => Connection::open(self.url())
                .unwrap()
                .query_row(sql, [], |r| r.get(0))
                .unwrap(),
            Db::Postgres(db) => db.client().await.query_one(sql, &[]).await.unwrap().get(0),
        }
    }
}
