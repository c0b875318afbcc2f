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
mod thermal_certificate;
mod thermal_combined;
mod thermal_export;
mod thermal_standards;
mod thermal_stored;
mod thermal_triad;
mod thermal_triad_combined;
mod thermal_triad_judged;
mod thermal_triad_static;
mod thermal_triad_stored;
mod trace;
mod traceability;
mod triad;
mod triads;
mod ui;
mod ui_live;
mod unchanged;
mod webhooks;

/// Checks `value` against the committed contract's schema `name`: every
/// required property present, no property it does not list.
pub fn conforms_to(name: &str, value: &serde_json::Value) {
    let doc: serde_json::Value =
        serde_norway::from_str(include_str!("../../openapi.yaml")).unwrap();
    let schema = &doc["components"]["schemas"][name];
    for required in schema["required"].as_array().unwrap() {
        assert!(
            value.get(required.as_str().unwrap()).is_some(),
            "{name}: {required} missing: {value}"
        );
    }
    for key in value.as_object().unwrap().keys() {
        assert!(
            schema["properties"].get(key).is_some(),
            "{name}: `{key}` is not in the contract: {value}"
        );
    }
}
