//! The API suite again, every test on PostgreSQL — a database of its own on
//! the server `ACCELCAL_TEST_POSTGRES_URL` names (the local one by default),
//! reached through a relay the outage tests can cut: the same tests as
//! `tests/api/`, with the idempotency races, outages and the access matrix
//! from `tests/reliability/`.

#[path = "../common/pg.rs"]
mod pg;

#[path = "../api/helpers.rs"]
mod helpers;

/// These tests run on PostgreSQL.
const ENGINE: helpers::Engine = helpers::Engine::Postgres;

#[path = "../api/contract.rs"]
mod contract;
#[path = "../api/endpoints.rs"]
mod endpoints;
#[path = "../api/errors.rs"]
mod errors;
#[path = "../api/metrology.rs"]
mod metrology;
#[path = "../api/paper.rs"]
mod paper;
#[path = "../api/restart.rs"]
mod restart;
#[path = "../api/ui.rs"]
mod ui;

#[path = "../reliability/access.rs"]
mod access;
#[path = "../reliability/idempotency.rs"]
mod idempotency;
#[path = "../reliability/outage.rs"]
mod outage;
