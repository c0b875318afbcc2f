//! The real `accelcal` binary as a process: kill -9 at random moments,
//! SIGTERM with a request in flight, and what it writes to its log.

mod crash;
mod server;
mod shutdown;
