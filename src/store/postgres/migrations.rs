//! Embedded migrations, applied at start under an advisory lock, so that
//! replicas starting together migrate once: the first takes the lock and
//! migrates, the others wait for it and then find nothing to do. Applied
//! versions are recorded in `accelcal_migrations`, each with its migration
//! in one transaction.

use deadpool_postgres::Pool;

use super::errors::{map, pool};
use crate::store::StoreError;

/// The migrations, oldest first.
const MIGRATIONS: &[&str] = &[
    include_str!("migrations/0001_schema.sql"),
    include_str!("migrations/0002_sensor_notify.sql"),
    include_str!("migrations/0003_cheaper_writes.sql"),
    include_str!("migrations/0004_token_notify.sql"),
    include_str!("migrations/0005_imports.sql"),
    include_str!("migrations/0006_token_holders.sql"),
    include_str!("migrations/0007_standards.sql"),
    include_str!("migrations/0008_signatures.sql"),
    include_str!("migrations/0009_customers.sql"),
    include_str!("migrations/0010_audit.sql"),
    include_str!("migrations/0011_nonconformities.sql"),
    include_str!("migrations/0012_triads.sql"),
    include_str!("migrations/0013_certificates.sql"),
    include_str!("migrations/0014_supersessions_indexed.sql"),
    include_str!("migrations/0015_audit_sealed.sql"),
    include_str!("migrations/0016_webhooks.sql"),
    include_str!("migrations/0017_thermal.sql"),
    include_str!("migrations/0018_thermal_triad.sql"),
];

/// The advisory lock key of migrations ("accelcal" in ASCII).
const LOCK: i64 = 0x6163_6365_6c63_616c;

/// Brings the database to the latest schema.
pub async fn migrate(p: &Pool) -> Result<(), StoreError> {
    let mut client = p.get().await.map_err(pool)?;
    client
        .execute("SELECT pg_advisory_lock($1)", &[&LOCK])
        .await
        .map_err(map)?;
    let outcome = apply(&mut client).await;
    let unlocked = client
        .execute("SELECT pg_advisory_unlock($1)", &[&LOCK])
        .await
        .map_err(map);
    outcome.and(unlocked.map(|_| ()))
}

async fn apply(client: &mut deadpool_postgres::Object) -> Result<(), StoreError> {
    client
        .batch_execute(
            "CREATE TABLE IF NOT EXISTS accelcal_migrations (\
             version integer PRIMARY KEY, applied_at timestamptz NOT NULL DEFAULT now())",
        )
        .await
        .map_err(map)?;
    let row = client
        .query_one(
            "SELECT coalesce(max(version), 0) FROM accelcal_migrations",
            &[],
        )
        .await
        .map_err(map)?;
    let applied: i32 = row.get(0);
    if applied as usize > MIGRATIONS.len() {
        return Err(StoreError::Unavailable(
            format!(
                "the database is at schema version {applied}, newer than this accelcal knows ({}); \
                 run a newer accelcal",
                MIGRATIONS.len()
            )
            .into(),
        ));
    }
    for (i, sql) in MIGRATIONS.iter().enumerate().skip(applied.max(0) as usize) {
        let version = i as i32 + 1;
        let tx = client.transaction().await.map_err(map)?;
        tx.batch_execute(sql).await.map_err(map)?;
        tx.execute(
            "INSERT INTO accelcal_migrations (version) VALUES ($1)",
            &[&version],
        )
        .await
        .map_err(map)?;
        tx.commit().await.map_err(map)?;
        tracing::info!(version, "applied a PostgreSQL migration");
    }
    Ok(())
}
