//! Tokens: only the hash of each secret is stored.

use deadpool_postgres::Object;
use uuid::Uuid;

use super::errors::map;
use super::rows::{self, TOKEN_COLUMNS};
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::StoreError;

/// Stores a new token.
pub async fn insert(client: &Object, t: &TokenRecord) -> Result<(), StoreError> {
    client
        .execute(
            &format!("INSERT INTO tokens ({TOKEN_COLUMNS}) VALUES ($1, $2, $3, $4, $5, $6, $7)"),
            &[
                &t.id,
                &t.secret_hash,
                &t.role.as_str(),
                &t.station_id,
                &t.label,
                &t.created_at.datetime(),
                &t.revoked_at.map(|r| r.datetime()),
            ],
        )
        .await
        .map_err(map)?;
    Ok(())
}

/// One token by id.
pub async fn get(client: &Object, id: Uuid) -> Result<Option<TokenRecord>, StoreError> {
    let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens WHERE id = $1");
    let stmt = client.prepare_cached(&sql).await.map_err(map)?;
    let row = client.query_opt(&stmt, &[&id]).await.map_err(map)?;
    row.as_ref().map(rows::token).transpose()
}

/// Every token, oldest first (ids are time-ordered).
pub async fn list(client: &Object) -> Result<Vec<TokenRecord>, StoreError> {
    let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens ORDER BY id");
    let found = client.query(&sql, &[]).await.map_err(map)?;
    found.iter().map(rows::token).collect()
}

/// Revokes an unrevoked token; whether there was one.
pub async fn revoke(client: &Object, id: Uuid, at: Timestamp) -> Result<bool, StoreError> {
    let n = client
        .execute(
            "UPDATE tokens SET revoked_at = $2 WHERE id = $1 AND revoked_at IS NULL",
            &[&id, &at.datetime()],
        )
        .await
        .map_err(map)?;
    Ok(n == 1)
}

/// Whether an unrevoked admin token exists.
pub async fn has_admin(client: &Object) -> Result<bool, StoreError> {
    let row = client
        .query_one(
            "SELECT EXISTS (SELECT 1 FROM tokens WHERE role = 'admin' AND revoked_at IS NULL)",
            &[],
        )
        .await
        .map_err(map)?;
    Ok(row.get(0))
}
