//! Web sessions: only the hash of each session id is stored.

use deadpool_postgres::Object;

use super::errors::{decode, map};
use super::rows;
use crate::domain::session::SessionRecord;
use crate::domain::timestamp::Timestamp;
use crate::store::StoreError;

/// Stores a new session and forgets every session that has expired.
pub async fn insert(client: &mut Object, s: &SessionRecord) -> Result<(), StoreError> {
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
}

/// One session by the hash of its id.
pub async fn get(client: &Object, id_hash: [u8; 32]) -> Result<Option<SessionRecord>, StoreError> {
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
}

/// Ends a session; whether there was one.
pub async fn delete(client: &Object, id_hash: [u8; 32]) -> Result<bool, StoreError> {
    let n = client
        .execute("DELETE FROM sessions WHERE id_hash = $1", &[&&id_hash[..]])
        .await
        .map_err(map)?;
    Ok(n == 1)
}
