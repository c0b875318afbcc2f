//! Reliability and security of the service: idempotency, limits, failing
//! storage, traceability and the bad-input corpus — over real HTTP.

#[path = "../api/helpers.rs"]
mod helpers;

mod access;
mod corpus;
mod idempotency;
mod limits;
mod storage;
mod traceability;
