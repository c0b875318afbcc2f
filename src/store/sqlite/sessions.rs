//! Web sessions: only the hash of each session id is stored.

use async_trait::async_trait;
use rusqlite::{OptionalExtension, params};

use super::SqliteStore;
use super::errors::map;
use crate::domain::session::SessionRecord;
use crate::domain::timestamp::Timestamp;
use crate::store::{Sessions, StoreError};

fn hash32(v: Vec<u8>, column: &str) -> Result<[u8; 32], StoreError> {
    v.try_into()
        .map_err(|_| StoreError::corrupt(format!("column `{column}`"), "not 32 bytes"))
}

#[async_trait]
impl Sessions for SqliteStore {
    /// Forgets every session that has expired, in the same transaction.
    async fn insert_session(&self, s: SessionRecord) -> Result<(), StoreError> {
        self.run("insert_session", move |conn| {
        let tx = conn.transaction().map_err(map)?;
        tx.execute(
            "DELETE FROM sessions WHERE expires_at <= ?1",
            [s.created_at.to_string()],
        )
        .map_err(map)?;
        tx.execute(
            "INSERT INTO sessions (id_hash, principal, credential_hash, csrf, created_at, expires_at) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            params![
                s.id_hash.to_vec(),
                s.principal,
                s.credential_hash.to_vec(),
                s.csrf,
                s.created_at.to_string(),
                s.expires_at.to_string()
            ],
        )
        .map_err(map)?;
        tx.commit().map_err(map)
        })
        .await
    }

    async fn session(&self, id_hash: [u8; 32]) -> Result<Option<SessionRecord>, StoreError> {
        self.run("session", move |conn| {
            let row = conn
                .query_row(
                    "SELECT principal, credential_hash, csrf, created_at, expires_at \
                 FROM sessions WHERE id_hash = ?1",
                    [id_hash.to_vec()],
                    |r| {
                        Ok((
                            r.get::<_, String>(0)?,
                            r.get::<_, Vec<u8>>(1)?,
                            r.get::<_, String>(2)?,
                            r.get::<_, String>(3)?,
                            r.get::<_, String>(4)?,
                        ))
                    },
                )
                .optional()
                .map_err(map)?;
            let Some((principal, credential, csrf, created, expires)) = row else {
                return Ok(None);
            };
            let time = |text: &str, column: &str| {
                Timestamp::parse(text)
                    .map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
            };
            Ok(Some(SessionRecord {
                id_hash,
                principal,
                credential_hash: hash32(credential, "credential_hash")?,
                csrf,
                created_at: time(&created, "created_at")?,
                expires_at: time(&expires, "expires_at")?,
            }))
        })
        .await
    }

    async fn delete_session(&self, id_hash: [u8; 32]) -> Result<bool, StoreError> {
        self.run("delete_session", move |conn| {
            let n = conn
                .execute(
                    "DELETE FROM sessions WHERE id_hash = ?1",
                    [id_hash.to_vec()],
                )
                .map_err(map)?;
            Ok(n == 1)
        })
        .await
    }
}
