//! The domain: what a submission, a token and a request body are, and the
//! rules they obey — independent of HTTP and of storage.
//!
//! Everything here is synchronous and free of I/O. It turns untrusted bytes
//! (JSON, CSV, header values) into checked values, reporting every fault with
//! the RFC 6901 pointer of the offending value ([`field`]), and holds the
//! limits the API promises ([`limits`]). The layers above — storage, the
//! HTTP API, the command line — import from here; nothing here imports
//! from them.

pub mod audit;
pub mod auth;
pub mod compensate;
pub mod customers;
pub mod dcc_signature;
pub mod events;
pub mod field;
pub mod fuse;
pub mod limits;
pub mod metrology;
pub mod nonconformity;
pub mod review;
pub mod schema;
pub mod sensor_types;
pub mod session;
pub mod standards;
pub mod status;
pub mod submission;
pub mod text;
pub mod thermal;
pub mod timestamp;
pub mod tokens;
pub mod triad;
pub mod triad_csv;
pub mod triad_export;
pub mod typed;
pub mod usability;
pub mod webhooks;
