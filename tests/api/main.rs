//! The service over real HTTP, in the test's own process: the paper end to
//! end, every endpoint, errors, the pages, restarts, idempotency, limits,
//! hardening, storage outages, request ids, the access matrix and the
//! bad-input corpus. Tests taking an `engine` run on SQLite and on
//! PostgreSQL (`#[values(Sqlite, Postgres)]`, rstest); the others test
//! what does not depend on the engine, on SQLite.

mod access;
mod audit;
mod authorship;
mod client;
mod contract;
mod corpus;
mod coverage;
mod customers;
mod dcc;
mod dcc_text;
mod endpoints;
mod errors;
mod events;
mod exports;
mod frozen;
mod hardening;
mod idempotency;
mod limits;
mod lost_updates;
mod metrology;
mod older;
mod out_of_service;
mod outage;
mod paper;
mod restart;
mod review;
mod round_four;
mod round_three;
mod signed;
mod standard_periods;
mod standards;
mod storage;
mod thermal;
mod trace;
mod traceability;
mod triad;
mod triads;
mod ui;
mod unchanged;
mod webhooks;
