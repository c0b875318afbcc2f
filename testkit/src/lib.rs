//! Test support shared by accelcal's test suites and benchmarks, so that
//! each suite is one test binary that imports what it needs:
//!
//! * [`app`]: a server in the test's own process on a fresh database of
//!   either [`Engine`], a client for it, and helpers for its answers;
//! * [`process`]: the real `accelcal` binary as a child process;
//! * [`pg`]: throwaway PostgreSQL databases, and a relay that can cut one
//!   off.

pub mod app;
pub mod pg;
pub mod process;
pub mod receiver;

pub use app::*;

/// `bytes` gzip-compressed, as a client sends a body with
/// `Content-Encoding: gzip`.
pub fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write as _;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).expect("writing to memory");
    e.finish().expect("writing to memory")
}
