//! Why a storage operation failed, with the driver's error kept as the source.

/// A boxed error from a database driver.
pub type BoxError = Box<dyn std::error::Error + Send + Sync>;

/// Why a storage operation failed.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The database cannot be used right now (busy, locked, missing,
    /// read-only, full, unreachable, I/O error). Retryable: answered 503.
    #[error("the database is unavailable")]
    Unavailable(#[source] BoxError),
    /// A constraint of the schema refused a write (a unique key, a foreign
    /// key, a check or trigger): a bug in accelcal, never the client's input.
    #[error("a database constraint refused the write")]
    Constraint(#[source] BoxError),
    /// Stored data does not decode: a bug or tampering, not retryable.
    #[error("stored {what} does not decode")]
    Corrupt {
        /// What was being read.
        what: String,
        /// Why it did not decode.
        #[source]
        source: BoxError,
    },
    /// Too many writes are already waiting for the database: the queue in
    /// front of the writer is full. Retryable at once: answered 503 with
    /// `Retry-After: 1`, so a burst costs a retry instead of unbounded
    /// latency and memory.
    #[error("{0} writes are already waiting for the database")]
    Overloaded(usize),
    /// A record the store refuses to write (a non-finite number).
    #[error("refused to store the record: {0}")]
    Refused(String),
    /// What the record was made from changed before it was stored: a
    /// calibration a temperature model was fitted from stopped counting
    /// (rejected, withdrawn, superseded or held) while the model was
    /// fitted. The client's input was right when it was read: answered
    /// 409 with this message, which names the calibration.
    #[error("{0}")]
    Conflict(String),
}

impl StoreError {
    /// A decoding failure of `what`.
    pub fn corrupt(what: impl Into<String>, source: impl Into<BoxError>) -> Self {
        StoreError::Corrupt {
            what: what.into(),
            source: source.into(),
        }
    }

    /// The error and every source beneath it, for logs.
    pub fn chain(&self) -> String {
        let mut out = self.to_string();
        let mut source = std::error::Error::source(self);
        while let Some(s) = source {
            out.push_str(": ");
            out.push_str(&s.to_string());
            source = s.source();
        }
        out
    }
}
