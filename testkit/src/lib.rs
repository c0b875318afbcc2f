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

pub use app::*;
