//! Logging: `tracing` to standard error, human-readable or JSON lines,
//! filtered by `RUST_LOG` (default `info`). Secrets are never logged: tokens
//! travel only in headers, and headers are not logged. The JSON lines are
//! written by [`json`].
//!
//! Lines are written **off the request path**: a request formats its line
//! and queues it; one thread writes the queue to standard error, many lines
//! per system call, flushing whenever the queue runs empty, so a log reader
//! that stalls (a full pipe) never stalls a request.
//! The queue holds at most [`QUEUE_LINES`] lines; past that, lines are
//! dropped rather than the service blocked, and counted
//! ([`dropped_lines`], the metric `accelcal_log_lines_dropped_total`).

mod json;

use std::io::BufWriter;
use std::sync::OnceLock;

use tracing_appender::non_blocking::{ErrorCounter, NonBlockingBuilder, WorkerGuard};
use tracing_subscriber::EnvFilter;

/// Log line format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LogFormat {
    /// Human-readable lines.
    Text,
    /// One JSON object per line.
    Json,
}

/// Lines queued at most before new ones are dropped (a line is a few
/// hundred bytes, so the queue holds a few MiB at worst).
pub const QUEUE_LINES: usize = 16_384;

/// Bytes the writer gathers before a system call, at most.
const WRITE_BUFFER: usize = 64 * 1024;

/// The lines dropped so far, once logging is initialised.
static DROPPED: OnceLock<ErrorCounter> = OnceLock::new();

/// Flushes the queued lines when dropped: hold it until the process ends.
#[must_use = "dropping the guard stops the log writer"]
pub struct LogGuard {
    _writer: Option<WorkerGuard>,
}

/// Installs the global subscriber (once per process) and starts the log
/// writer; lines still queued are written when the guard is dropped.
pub fn init(format: LogFormat) -> LogGuard {
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let (writer, guard) = NonBlockingBuilder::default()
        .buffered_lines_limit(QUEUE_LINES)
        .lossy(true)
        .thread_name("accelcal-log")
        // The writer thread flushes whenever its queue runs empty, so a
        // line waits in the buffer only while more are being written.
        .finish(BufWriter::with_capacity(WRITE_BUFFER, std::io::stderr()));
    let counter = writer.error_counter();
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(writer)
        .with_ansi(ansi);
    let installed = match format {
        LogFormat::Text => builder.try_init(),
        LogFormat::Json => builder
            .fmt_fields(json::JsonFields)
            .event_format(json::JsonLine)
            .try_init(),
    };
    if installed.is_err() {
        // A subscriber was already installed (tests): this writer is unused.
        return LogGuard { _writer: None };
    }
    let _ = DROPPED.set(counter);
    LogGuard {
        _writer: Some(guard),
    }
}

/// Log lines dropped because the queue was full (0 before [`init`]).
pub fn dropped_lines() -> u64 {
    DROPPED.get().map_or(0, |c| c.dropped_lines() as u64)
}
