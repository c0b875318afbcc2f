//! Idempotency keys (IETF draft "The Idempotency-Key HTTP Header Field"):
//! claimed with a lease before a request's work starts, completed in the
//! calibration's own transaction ([`super::calibrations::insert`]),
//! released when the request stores nothing.

use async_trait::async_trait;
use rusqlite::{Connection, params};

use super::SqliteStore;
use super::errors::map;
use super::rows;
use crate::domain::timestamp::Timestamp;
use crate::store::{
    Claim, DoneKey, IDEMPOTENCY_RETENTION_SECONDS, Idempotency, IdempotencyKey, StoreError,
};

/// What a key's row holds.
struct KeyRow {
    request_hash: Vec<u8>,
    calibration_id: Option<String>,
    locked_until: Option<String>,
}

/// Claims `k` until `lease_until`; forgets keys past the retention period.
/// Runs inside a transaction (the writer's savepoint) that the caller
/// commits whatever the answer.
fn claim(
    tx: &Connection,
    k: &IdempotencyKey,
    now: Timestamp,
    lease_until: Timestamp,
) -> Result<Claim, StoreError> {
    let horizon = now.plus_seconds(-IDEMPOTENCY_RETENTION_SECONDS).to_string();
    rows::execute(
        tx,
        "DELETE FROM idempotency_keys WHERE created_at < ?1",
        [horizon],
    )?;
    let row = rows::first(
        tx,
        "SELECT request_hash, calibration_id, locked_until FROM idempotency_keys \
         WHERE principal = ?1 AND key = ?2",
        params![k.principal, k.key],
        |r| {
            Ok(KeyRow {
                request_hash: r.get("request_hash").map_err(map)?,
                calibration_id: r.get("calibration_id").map_err(map)?,
                locked_until: r.get("locked_until").map_err(map)?,
            })
        },
    )?;
    let now_text = now.to_string();
    let claim = match row {
        Some(r) if r.request_hash != k.request_hash => Claim::Mismatch,
        Some(KeyRow {
            calibration_id: Some(id),
            ..
        }) => Claim::Done(
            uuid::Uuid::try_parse(&id).map_err(|e| StoreError::corrupt("idempotency key", e))?,
        ),
        Some(KeyRow {
            locked_until: Some(until),
            ..
        }) if until > now_text => Claim::InFlight,
        Some(_) => {
            rows::execute(
                tx,
                "UPDATE idempotency_keys SET locked_until = ?3, holder = ?4 \
                 WHERE principal = ?1 AND key = ?2",
                params![
                    k.principal,
                    k.key,
                    lease_until.to_string(),
                    k.holder.to_string()
                ],
            )?;
            Claim::Fresh
        }
        None => {
            rows::execute(
                tx,
                "INSERT INTO idempotency_keys (principal, key, request_hash, locked_until, created_at, holder) \
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                params![
                    k.principal,
                    k.key,
                    k.request_hash.to_vec(),
                    lease_until.to_string(),
                    now_text,
                    k.holder.to_string()
                ],
            )?;
            Claim::Fresh
        }
    };
    Ok(claim)
}

/// Gives up a claimed key whose request stored nothing, if that request
/// still holds its lease.
fn release(conn: &Connection, k: &IdempotencyKey) -> Result<(), StoreError> {
    conn.execute(
        "DELETE FROM idempotency_keys WHERE principal = ?1 AND key = ?2 \
         AND calibration_id IS NULL AND holder = ?3",
        params![k.principal, k.key, k.holder.to_string()],
    )
    .map_err(map)?;
    Ok(())
}

/// Frees every lease (at open: one process owns a SQLite database, so no
/// request of an earlier process can still be in flight, and retries after
/// a crash need not wait for the leases to expire).
pub fn free_leases(conn: &Connection) -> Result<(), StoreError> {
    conn.execute(
        "UPDATE idempotency_keys SET locked_until = NULL \
         WHERE calibration_id IS NULL AND locked_until IS NOT NULL",
        [],
    )
    .map_err(map)?;
    Ok(())
}

#[async_trait]
impl Idempotency for SqliteStore {
    async fn claim_key(
        &self,
        k: IdempotencyKey,
        now: Timestamp,
        lease_until: Timestamp,
    ) -> Result<Claim, StoreError> {
        self.write("claim_key", move |conn| {
            Ok((claim(conn, &k, now, lease_until)?, true))
        })
        .await
    }

    async fn release_key(&self, key: IdempotencyKey) -> Result<(), StoreError> {
        self.write("release_key", move |conn| Ok((release(conn, &key)?, true)))
            .await
    }

    async fn done_keys(&self, since: Timestamp) -> Result<Vec<DoneKey>, StoreError> {
        self.run("done_keys", move |conn| {
    rows::all(
        conn,
        "SELECT principal, key, request_hash, calibration_id, created_at FROM idempotency_keys \
         WHERE calibration_id IS NOT NULL AND created_at >= ?1 ORDER BY principal, key",
        [since.to_string()],
        |r| {
            let hash: Vec<u8> = r.get("request_hash").map_err(map)?;
            let created: String = r.get("created_at").map_err(map)?;
            Ok(DoneKey {
                principal: r.get("principal").map_err(map)?,
                key: r.get("key").map_err(map)?,
                request_hash: hash
                    .try_into()
                    .map_err(|_| StoreError::corrupt("column `request_hash`", "not 32 bytes"))?,
                calibration_id: rows::uuid(r, "calibration_id")?,
                created_at: Timestamp::parse(&created)
                    .map_err(|e| StoreError::corrupt("column `created_at`", e))?,
            })
        },
    )
        })
        .await
    }

    async fn put_done_key(&self, k: DoneKey) -> Result<(), StoreError> {
        self.run("put_done_key", move |conn| {
            conn.execute(
        "INSERT INTO idempotency_keys (principal, key, request_hash, calibration_id, created_at) \
         VALUES (?1, ?2, ?3, ?4, ?5)",
        params![
            k.principal,
            k.key,
            k.request_hash.to_vec(),
            k.calibration_id.to_string(),
            k.created_at.to_string()
        ],
    )
    .map_err(map)?;
            Ok(())
        })
        .await
    }
}
