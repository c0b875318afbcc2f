//! # accelcal
//!
//! A calibration service for pendulous accelerometers: test stations submit
//! tumble tests; accelcal identifies the static model of every run, fuses the
//! runs by batch estimation ([`accelcal_core`]), stores the raw submission and
//! the results, and serves coefficients, uncertainty, decisions, history,
//! stability and compensation over HTTP, with web pages and certificates.
//!
//! The layers, each importing only from those before it:
//!
//! * [`accelcal_core`]: the maths (pure, its own crate);
//! * [`domain`]: submissions and their JSON and CSV formats, limits, tokens
//!   and roles, request bodies — checked values, no I/O;
//! * [`store`]: storage behind one trait — SQLite, or PostgreSQL for
//!   several replicas — with the sensor and token caches in front;
//! * [`app`]: the laboratory's acts (submit, review, supersede,
//!   reprocess), each over the store and the domain, with no HTTP in it;
//! * [`http`]: the API (routes, middleware, problem documents, OpenAPI,
//!   metrics) and the web pages;
//! * [`startup`]: configuration, the accept loop, shutdown;
//! * [`cli`] (with [`client`]): the `accelcal` command line;
//! * [`telemetry`], logging.
//!
//! `docs/developers.md` says what a new endpoint, query or stored field
//! touches.

// The service's documentation is for those who work on it, and links the
// private items a module's map names (`cargo doc --document-private-items`
// renders them).
#![allow(rustdoc::private_intra_doc_links)]

pub mod app;
pub mod cli;
pub mod client;
pub mod domain;
pub mod http;
pub mod startup;
pub mod store;
pub mod telemetry;
