//! Tokens: only the hash of each secret is stored.

use rusqlite::{Connection, params};
use uuid::Uuid;

use super::errors::map;
use super::rows::{self, TOKEN_COLUMNS};
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::StoreError;

/// Stores a new token.
pub fn insert(conn: &Connection, t: &TokenRecord) -> Result<(), StoreError> {
    conn.execute(
        &format!("INSERT INTO tokens ({TOKEN_COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)"),
        params![
            t.id.to_string(),
            t.secret_hash,
            t.role.as_str(),
            t.station_id,
            t.label,
            t.created_at.to_string(),
            t.revoked_at.map(|r| r.to_string())
        ],
    )
    .map_err(map)?;
    Ok(())
}

/// One token by id.
pub fn get(conn: &Connection, id: Uuid) -> Result<Option<TokenRecord>, StoreError> {
    let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens WHERE id = ?1");
    rows::first(conn, &sql, [id.to_string()], rows::token)
}

/// Every token, oldest first (ids are time-ordered).
pub fn list(conn: &Connection) -> Result<Vec<TokenRecord>, StoreError> {
    let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens ORDER BY id");
    rows::all(conn, &sql, [], rows::token)
}

/// Revokes an unrevoked token; whether there was one.
pub fn revoke(conn: &Connection, id: Uuid, at: Timestamp) -> Result<bool, StoreError> {
    let n = conn
        .execute(
            "UPDATE tokens SET revoked_at = ?2 WHERE id = ?1 AND revoked_at IS NULL",
            params![id.to_string(), at.to_string()],
        )
        .map_err(map)?;
    Ok(n == 1)
}

/// Whether an unrevoked admin token exists.
pub fn has_admin(conn: &Connection) -> Result<bool, StoreError> {
    conn.query_row(
        "SELECT EXISTS (SELECT 1 FROM tokens WHERE role = 'admin' AND revoked_at IS NULL)",
        [],
        |r| r.get(0),
    )
    .map_err(map)
}
