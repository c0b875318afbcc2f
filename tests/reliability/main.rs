//! Reliability and security of the service: idempotency, limits, failing
//! storage, traceability and the bad-input corpus — over real HTTP.

#[path = "../common/pg.rs"]
mod pg;

#[path = "../api/helpers.rs"]
mod helpers;

/// These tests run on SQLite (the idempotency races also run on PostgreSQL,
/// in `tests/api_postgres/`).
const ENGINE: helpers::Engine = helpers::Engine::Sqlite;

mod access;
mod client;
mod corpus;
mod hardening;
mod idempotency;
mod limits;
mod outage;
mod round_three;
mod storage;
mod traceability;
