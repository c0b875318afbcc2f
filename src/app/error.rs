//! What an act refuses, in the laboratory's terms: the one error type of
//! the application layer. Each transport says it its own way — the HTTP
//! layer as a problem document (`crate::http::problem`), the command line
//! as a message — and every refusal that concerns the input names the
//! field at fault.

use crate::domain::field::Invalid;
use crate::domain::submission::Refused;
use crate::domain::typed::BodyError;
use crate::store::StoreError;

/// Why an act was not done.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The input cannot be read as its media type (not JSON, not UTF-8).
    #[error("{0}")]
    Unreadable(String),
    /// The input was read, but fields are wrong: each named.
    #[error("{0}")]
    Invalid(Invalid),
    /// The principal may not do this; with the fields at fault when what
    /// it may not do is set a field.
    #[error("{why}")]
    Forbidden {
        /// Why not.
        why: String,
        /// The fields at fault, if it is a field.
        fields: Option<Invalid>,
    },
    /// No such record.
    #[error("{0}")]
    NotFound(String),
    /// The calibration's state does not allow the act.
    #[error("{0}")]
    State(String),
    /// Single-axis and triad calibrations do not mix: a sensor's
    /// calibrations are all of one kind (the submission's `sensor_id` is at
    /// fault).
    #[error("{0}")]
    WrongKind(String),
    /// A request with the same idempotency key is still being processed.
    #[error("a request with the same idempotency key is still being processed")]
    InFlight,
    /// The idempotency key was used before with a different input.
    #[error("the idempotency key was used before with a different input")]
    KeyReused,
    /// The store failed (unavailable, overloaded, or a fault).
    #[error(transparent)]
    Store(StoreError),
    /// A fault of accelcal's own, logged where it happened.
    #[error("a fault of accelcal's own (see the log)")]
    Internal,
}

impl Error {
    /// Fields are wrong: `why` at `at`.
    pub fn invalid(at: impl std::fmt::Display, why: impl Into<String>) -> Self {
        Error::Invalid(Invalid::one(at, why))
    }
}

impl From<StoreError> for Error {
    fn from(e: StoreError) -> Self {
        match e {
            StoreError::Conflict(why) => Error::State(why),
            e => Error::Store(e),
        }
    }
}

impl From<Invalid> for Error {
    fn from(invalid: Invalid) -> Self {
        Error::Invalid(invalid)
    }
}

impl From<BodyError> for Error {
    fn from(e: BodyError) -> Self {
        match e {
            BodyError::Syntax(m) => Error::Unreadable(format!("the body is not valid JSON: {m}")),
            BodyError::Invalid(i) => Error::Invalid(i),
        }
    }
}

impl From<Refused> for Error {
    fn from(e: Refused) -> Self {
        match e {
            Refused::Unreadable(u) => Error::Unreadable(u.to_string()),
            Refused::Invalid(i) => Error::Invalid(i),
        }
    }
}
