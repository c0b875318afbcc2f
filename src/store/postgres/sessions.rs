//! Web sessions: only the hash of each session id is stored.

use async_trait::async_trait;

use super::PostgresStore;
use super::errors::{decode, map};
use super::rows;
use crate::domain::session::SessionRecord;
use crate::domain::timestamp::Timestamp;
use crate::store::{Sessions, StoreError};

#[async_trait]
impl Sessions for PostgresStore {
    async fn insert_session(&self, s: SessionRecord) -> Result<(), StoreError> {
        op!(self, "insert_session", |client| {
            let tx = client.transaction().await.map_err(map)?;
            tx.execute(
                "DELETE FROM sessions WHERE expires_at <= $1",
                &[&s.created_at.datetime()],
            )
            .await
            .map_err(map)?;
            tx.execute(
            "INSERT INTO sessions (id_hash, principal, credential_hash, csrf, created_at, expires_at) \
             VALUES ($1, $2, $3, $4, $5, $6)",
            &[
                &&s.id_hash[..],
                &s.principal,
                &&s.credential_hash[..],
                &s.csrf,
                &s.created_at.datetime(),
                &s.expires_at.datetime(),
            ],
        )
        .await
        .map_err(map)?;
            tx.commit().await.map_err(map)
        })
    }

    async fn session(&self, id_hash: [u8; 32]) -> Result<Option<SessionRecord>, StoreError> {
        op!(self, "session", |client| {
            let row = client
                .query_opt(
                    "SELECT principal, credential_hash, csrf, created_at, expires_at \
                 FROM sessions WHERE id_hash = $1",
                    &[&&id_hash[..]],
                )
                .await
                .map_err(map)?;
            let Some(row) = row else { return Ok(None) };
            let credential: Vec<u8> = rows::get(&row, "credential_hash")?;
            Ok(Some(SessionRecord {
                id_hash,
                principal: rows::get(&row, "principal")?,
                credential_hash: credential
                    .try_into()
                    .map_err(|_| decode("credential_hash", "not 32 bytes"))?,
                csrf: rows::get(&row, "csrf")?,
                created_at: Timestamp::from_datetime(rows::get(&row, "created_at")?),
                expires_at: Timestamp::from_datetime(rows::get(&row, "expires_at")?),
            }))
        })
    }

    async fn delete_session(&self, id_hash: [u8; 32]) -> Result<bool, StoreError> {
        op!(self, "delete_session", |client| {
            let n = client
                .execute("DELETE FROM sessions WHERE id_hash = $1", &[&&id_hash[..]])
                .await
                .map_err(map)?;
            Ok(n == 1)
        })
    }
}
