//! # accelcal
//!
//! A calibration service for pendulous accelerometers: test stations submit
//! tumble tests; accelcal identifies the static model of every run, fuses the
//! runs by batch estimation ([`accelcal_core`]), stores the raw submission and
//! the results, and serves coefficients, history and compensation over HTTP.
//!
//! The layers, each importing only from those before it:
//!
//! * [`accelcal_core`]: the maths (pure, its own crate);
//! * [`domain`]: submissions and their JSON and CSV formats, limits, tokens
//!   and roles, request bodies — checked values, no I/O;
//! * [`store`]: storage behind one trait (SQLite);
//! * [`http`]: the API (routes, middleware, problem documents, OpenAPI);
//! * [`startup`]: configuration, the accept loop, shutdown;
//! * [`cli`] (with [`client`]): the `accelcal` command line.

pub mod cli;
pub mod client;
pub mod domain;
pub mod http;
pub mod startup;
pub mod store;
pub mod telemetry;
