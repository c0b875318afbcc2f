//! Idempotency keys, claimed across replicas: the key's row is inserted, or
//! locked (`FOR UPDATE`) and judged, inside one transaction, so two replicas
//! claiming one key at the same moment are served one after the other — the
//! first gets the lease, the second sees it in flight (or, later, done).
//! Leases carry their holder: a request releases a key only while it holds
//! it, and a crashed replica's leases simply expire.

use async_trait::async_trait;
use uuid::Uuid;

use super::PostgresStore;
use super::errors::map;
use super::rows;
use crate::domain::timestamp::Timestamp;
use crate::store::{
    Claim, DoneKey, IDEMPOTENCY_RETENTION_SECONDS, Idempotency, IdempotencyKey, StoreError,
};

#[async_trait]
impl Idempotency for PostgresStore {
    async fn claim_key(
        &self,
        k: IdempotencyKey,
        now: Timestamp,
        lease_until: Timestamp,
    ) -> Result<Claim, StoreError> {
        op!(self, "claim_key", |client| {
            let tx = client.transaction().await.map_err(map)?;
            let horizon = now.plus_seconds(-IDEMPOTENCY_RETENTION_SECONDS).datetime();
            tx.execute(
                "DELETE FROM idempotency_keys WHERE created_at < $1",
                &[&horizon],
            )
            .await
            .map_err(map)?;
            let inserted = tx
            .execute(
                "INSERT INTO idempotency_keys (principal, key, request_hash, locked_until, holder, created_at) \
                 VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (principal, key) DO NOTHING",
                &[
                    &k.principal,
                    &k.key,
                    &&k.request_hash[..],
                    &lease_until.datetime(),
                    &k.holder,
                    &now.datetime(),
                ],
            )
            .await
            .map_err(map)?;
            let claim = if inserted == 1 {
                Claim::Fresh
            } else {
                let row = tx
                    .query_one(
                        "SELECT request_hash, calibration_id, locked_until FROM idempotency_keys \
                     WHERE principal = $1 AND key = $2 FOR UPDATE",
                        &[&k.principal, &k.key],
                    )
                    .await
                    .map_err(map)?;
                let hash: Vec<u8> = rows::get(&row, "request_hash")?;
                let done: Option<Uuid> = rows::get(&row, "calibration_id")?;
                let until: Option<time::OffsetDateTime> = rows::get(&row, "locked_until")?;
                match (done, until) {
                    _ if hash != k.request_hash => Claim::Mismatch,
                    (Some(id), _) => Claim::Done(id),
                    (None, Some(until)) if Timestamp::from_datetime(until) > now => Claim::InFlight,
                    (None, _) => {
                        tx.execute(
                            "UPDATE idempotency_keys SET locked_until = $3, holder = $4 \
                         WHERE principal = $1 AND key = $2",
                            &[&k.principal, &k.key, &lease_until.datetime(), &k.holder],
                        )
                        .await
                        .map_err(map)?;
                        Claim::Fresh
                    }
                }
            };
            tx.commit().await.map_err(map)?;
            Ok(claim)
        })
    }

    async fn release_key(&self, k: IdempotencyKey) -> Result<(), StoreError> {
        op!(self, "release_key", |client| {
            client
                .execute(
                    "DELETE FROM idempotency_keys WHERE principal = $1 AND key = $2 \
                 AND calibration_id IS NULL AND holder = $3",
                    &[&k.principal, &k.key, &k.holder],
                )
                .await
                .map_err(map)?;
            Ok(())
        })
    }

    async fn done_keys(&self, since: Timestamp) -> Result<Vec<DoneKey>, StoreError> {
        op!(self, "done_keys", |client| {
            let found = client
            .query(
                "SELECT principal, key, request_hash, calibration_id, created_at FROM idempotency_keys \
                 WHERE calibration_id IS NOT NULL AND created_at >= $1 ORDER BY principal, key",
                &[&since.datetime()],
            )
            .await
            .map_err(map)?;
            found
                .iter()
                .map(|r| {
                    let hash: Vec<u8> = rows::get(r, "request_hash")?;
                    Ok(DoneKey {
                        principal: rows::get(r, "principal")?,
                        key: rows::get(r, "key")?,
                        request_hash: hash
                            .try_into()
                            .map_err(|_| super::errors::decode("request_hash", "not 32 bytes"))?,
                        calibration_id: rows::get(r, "calibration_id")?,
                        created_at: Timestamp::from_datetime(rows::get(r, "created_at")?),
                    })
                })
                .collect()
        })
    }

    async fn put_done_key(&self, k: DoneKey) -> Result<(), StoreError> {
        op!(self, "put_done_key", |client| {
            client
            .execute(
                "INSERT INTO idempotency_keys (principal, key, request_hash, calibration_id, created_at) \
                 VALUES ($1, $2, $3, $4, $5)",
                &[
                    &k.principal,
                    &k.key,
                    &&k.request_hash[..],
                    &k.calibration_id,
                    &k.created_at.datetime(),
                ],
            )
            .await
            .map_err(map)?;
            Ok(())
        })
    }
}
