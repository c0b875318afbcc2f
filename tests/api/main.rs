//! API tests over real HTTP against a server bound to a free port.

#[path = "../common/pg.rs"]
mod pg;

/// These tests run on SQLite (`tests/api_postgres/` runs them on PostgreSQL).
const ENGINE: helpers::Engine = helpers::Engine::Sqlite;

mod contract;
mod endpoints;
mod errors;
mod helpers;
mod metrology;
mod paper;
mod restart;
mod ui;
