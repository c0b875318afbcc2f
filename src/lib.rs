//! # accelcal
//!
//! A calibration service for pendulous accelerometers: test stations submit
//! tumble tests; accelcal identifies the static model of every run, fuses the
//! runs by batch estimation ([`accelcal_core`]), stores the raw submission and
//! the results, and serves coefficients, history and compensation over HTTP.
//!
//! * [`startup::Application`] binds and runs the server;
//! * [`http`] is the API (routes, middleware, problem documents);
//! * [`submission`] and [`input`] turn request bodies into core types;
//! * [`store`] keeps calibrations and tokens (SQLite);
//! * [`cli`] is the `accelcal` command line.

pub mod auth;
pub mod cli;
pub mod client;
pub mod http;
pub mod input;
pub mod startup;
pub mod store;
pub mod submission;
pub mod telemetry;
pub mod timestamp;
