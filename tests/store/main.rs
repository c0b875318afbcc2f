//! The storage layer, against real databases (a SQLite file, a PostgreSQL
//! database of its own per test):
//!
//! * [`conformance`]: the engine-agnostic suite of the `Store` trait, which
//!   every engine runs (a new engine adds one `#[tokio::test]` that builds
//!   it and calls `conformance::conformance`), bare and behind the cache;
//! * [`engines`]: each engine's own promises — its schema's refusals,
//!   durable commits, TLS, leases, its pool;
//! * [`cache`]: the sensor cache kept up to date by writes;
//! * [`replicas`]: several handles or replicas on one database;
//! * [`group_commit`]: PostgreSQL's batches, held and released
//!   deterministically;
//! * [`fitted`]: a temperature model's constituents checked where it is
//!   stored;
//! * [`webhooks`]: endpoints' leases, settles and redelivery (in the
//!   conformance suite), and two replicas claiming at once.

use std::sync::Arc;

mod audit;
mod cache;
mod conformance;
mod engines;
mod fitted;
mod group_commit;
mod replicas;
mod webhooks;

use accelcal::domain::auth::Role;
use accelcal::domain::sensor_types::SensorType;
use accelcal::domain::status::Status;
use accelcal::domain::timestamp::Timestamp;
use accelcal::domain::tokens::TokenRecord;
use accelcal::store::cache::SensorCache;
use accelcal::store::prelude::*;
use accelcal::store::{
    Claim, HistoryQuery, IdempotencyKey, NewCalibration, SensorQuery, StoreError, Stored,
    postgres::PostgresStore, sqlite::SqliteStore,
};
use accelcal_core::decision::{Limit, Rule, Verdict};
use accelcal_core::{Model, Term, TermMap};
use accelcal_testkit::pg;
use bytes::Bytes;
use cache::{cached_replica, cut_listeners};
use conformance::sensor_type;
use uuid::Uuid;

fn t(s: &str) -> Timestamp {
    Timestamp::parse(s).unwrap()
}

fn calibration(sensor: &str, performed_at: &str) -> NewCalibration {
    let id = Uuid::now_v7();
    NewCalibration {
        id,
        sensor_id: sensor.into(),
        station_id: Some("LAB-1".into()),
        performed_at: t(performed_at),
        received_at: t("2026-11-22T00:00:00Z"),
        unit: "mA".into(),
        model: Model::new(vec![Term::K0, Term::Ki]).unwrap(),
        runs: 4,
        coefficients: TermMap(vec![(Term::K0, 0.001), (Term::Ki, -1.2)]),
        std_errors: TermMap(vec![(Term::K0, 1e-6), (Term::Ki, 2e-6)]),
        result: Bytes::from(format!(r#"{{"id":"{id}"}}"#)),
        submission: Bytes::from_static(b"{\"raw\": true}"),
        content_type: "application/json".into(),
        submitted_by: "tester".into(),
        sensor_type: None,
        assigns_type: false,
        verdict: None,
        due_at: None,
        expanded: Some(TermMap(vec![(Term::K0, 2e-6), (Term::Ki, 4e-6)])),
        triad: None,
        thermal: None,
        thermal_triad: None,
        standards: Vec::new(),
        fitted_from: Vec::new(),
    }
}

/// The actor of the tests' administrative writes.
fn admin() -> accelcal::domain::audit::Actor {
    accelcal::domain::audit::Actor {
        token_id: "0190aaaa000070008000000000000009".into(),
        role: "admin".into(),
        holder: Some("Ada".into()),
    }
}

fn now() -> Timestamp {
    t("2026-11-22T00:00:00Z")
}

fn all_sensors(after: Option<String>, limit: usize) -> SensorQuery {
    SensorQuery {
        after,
        status: None,
        search: None,
        now: now(),
        limit,
    }
}

fn key(k: &str, body: u8) -> IdempotencyKey {
    IdempotencyKey {
        principal: "p-1".into(),
        key: k.into(),
        request_hash: [body; 32],
        holder: Uuid::from_u128(u128::from(body)),
    }
}

/// Polls `done` every 2 ms for up to 10 s.
async fn until(mut done: impl FnMut() -> bool, what: &str) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while !done() {
        assert!(
            std::time::Instant::now() < deadline,
            "waited 10 s for {what}"
        );
        tokio::time::sleep(std::time::Duration::from_millis(2)).await;
    }
}
