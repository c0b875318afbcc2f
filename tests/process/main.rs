//! The real `accelcal` binary as a process: kill -9 at random moments,
//! SIGTERM with a request in flight, and what it writes to its log.

mod cli;
mod crash;
mod db;
mod logs;
mod metrics;
mod migrate;
mod replicas;
mod shutdown;
mod sqlite_file;
mod verify;
