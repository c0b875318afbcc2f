//! Embedded migrations, applied in order; `PRAGMA user_version` counts those
//! applied. Every connection checks on open, and applies what is missing
//! under the write lock (so two connections never both migrate).

use rusqlite::{Connection, TransactionBehavior};

/// The migrations, oldest first.
const MIGRATIONS: &[&str] = &[
    include_str!("migrations/0001_init.sql"),
    include_str!("migrations/0002_idempotency.sql"),
    include_str!("migrations/0003_finite_and_immutable.sql"),
    include_str!("migrations/0004_metrology.sql"),
    include_str!("migrations/0005_sessions.sql"),
    include_str!("migrations/0006_lease_holders.sql"),
];

/// Brings the database to the latest schema.
pub fn migrate(conn: &mut Connection) -> rusqlite::Result<()> {
    let latest = MIGRATIONS.len() as i64;
    let version: i64 = conn.pragma_query_value(None, "user_version", |r| r.get(0))?;
    if version >= latest {
        return Ok(());
    }
    let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
    // Re-read under the write lock: another connection may have migrated.
    let version: i64 = tx.pragma_query_value(None, "user_version", |r| r.get(0))?;
    for sql in MIGRATIONS.iter().skip(version.max(0) as usize) {
        tx.execute_batch(sql)?;
    }
    tx.pragma_update(None, "user_version", latest)?;
    tx.commit()
}
