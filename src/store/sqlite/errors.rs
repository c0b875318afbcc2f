//! rusqlite's errors mapped to [`StoreError`], keeping the driver's error as
//! the source.

use rusqlite::ErrorCode;

use crate::store::StoreError;

/// Maps a driver error: decoding failures are corrupt data, constraint
/// violations are constraints, everything else is the database being
/// unavailable (busy, locked, read-only, full, I/O, cannot open).
pub fn map(e: rusqlite::Error) -> StoreError {
    match e {
        rusqlite::Error::FromSqlConversionFailure(..)
        | rusqlite::Error::InvalidColumnType(..)
        | rusqlite::Error::InvalidColumnName(..)
        | rusqlite::Error::IntegralValueOutOfRange(..) => StoreError::corrupt("a row", e),
        rusqlite::Error::SqliteFailure(f, _) if f.code == ErrorCode::ConstraintViolation => {
            StoreError::Constraint(Box::new(e))
        }
        other => StoreError::Unavailable(Box::new(other)),
    }
}

/// SQLite's error code beneath a store error, if there is one.
fn code(e: &StoreError) -> Option<ErrorCode> {
    std::error::Error::source(e)
        .and_then(|s| s.downcast_ref::<rusqlite::Error>())
        .and_then(rusqlite::Error::sqlite_error_code)
}

/// Whether a store error is SQLite's "database is locked" (`SQLITE_BUSY`).
pub fn is_busy(e: &StoreError) -> bool {
    code(e) == Some(ErrorCode::DatabaseBusy)
}

/// Whether a store error is SQLite's "database or disk is full".
pub fn is_full(e: &StoreError) -> bool {
    code(e) == Some(ErrorCode::DiskFull)
}

#[cfg(test)]
mod tests {
    use rusqlite::ffi;

    use super::*;

    fn failure(code: i32) -> rusqlite::Error {
        rusqlite::Error::SqliteFailure(ffi::Error::new(code), None)
    }

    #[test]
    fn outages_are_unavailable_constraints_and_decoding_are_not() {
        for code in [
            ffi::SQLITE_BUSY,
            ffi::SQLITE_LOCKED,
            ffi::SQLITE_READONLY,
            ffi::SQLITE_FULL,
            ffi::SQLITE_IOERR,
            ffi::SQLITE_CANTOPEN,
            ffi::SQLITE_CORRUPT,
        ] {
            assert!(
                matches!(map(failure(code)), StoreError::Unavailable(_)),
                "code {code}"
            );
        }
        let constraint = map(failure(ffi::SQLITE_CONSTRAINT));
        assert!(matches!(constraint, StoreError::Constraint(_)));
        assert!(
            std::error::Error::source(&constraint).is_some(),
            "the driver error is kept"
        );
        let decode =
            rusqlite::Error::InvalidColumnType(0, "id".into(), rusqlite::types::Type::Null);
        assert!(matches!(map(decode), StoreError::Corrupt { .. }));
    }
}
