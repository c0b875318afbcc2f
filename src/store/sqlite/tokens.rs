//! Tokens: only the hash of each secret is stored. Reads go through the
//! token cache ([`crate::store::cache::tokens`]).

use async_trait::async_trait;
use rusqlite::params;
use uuid::Uuid;

use super::errors::map;
use super::rows::{self, TOKEN_COLUMNS};
use super::{SqliteStore, audit};
use crate::domain::audit::Actor;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::{StoreError, Tokens};

#[async_trait]
impl Tokens for SqliteStore {
    async fn insert_token(&self, t: TokenRecord, by: Actor) -> Result<(), StoreError> {
        self.write("insert_token", move |conn| {
            conn.execute(
                &format!(
                    "INSERT INTO tokens ({TOKEN_COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)"
                ),
                params![
                    t.id.to_string(),
                    t.secret_hash,
                    t.role.as_str(),
                    t.station_id,
                    t.label,
                    t.created_at.to_string(),
                    t.revoked_at.map(|r| r.to_string()),
                    t.holder
                ],
            )
            .map_err(map)?;
            audit::append(conn, crate::store::audit::token_created(&t, by))?;
            Ok(((), true))
        })
        .await
    }

    async fn token(&self, id: Uuid) -> Result<Option<TokenRecord>, StoreError> {
        self.follow_the_file()?;
        let read = self.run("token", move |conn| {
            let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens WHERE id = ?1");
            rows::first(conn, &sql, [id.to_string()], rows::token)
        });
        self.cache.token(id, read).await
    }

    /// Oldest first (ids are time-ordered).
    async fn tokens(&self) -> Result<Vec<TokenRecord>, StoreError> {
        self.run("tokens", |conn| {
            let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens ORDER BY id");
            rows::all(conn, &sql, [], rows::token)
        })
        .await
    }

    async fn revoke_token(&self, id: Uuid, at: Timestamp, by: Actor) -> Result<bool, StoreError> {
        self.follow_the_file()?;
        let this = self.clone();
        let revoke = async move {
            this.write("revoke_token", move |conn| {
                let n = conn
                    .execute(
                        "UPDATE tokens SET revoked_at = ?2 WHERE id = ?1 AND revoked_at IS NULL",
                        params![id.to_string(), at.to_string()],
                    )
                    .map_err(map)?;
                if n == 1 {
                    audit::append(conn, crate::store::audit::token_revoked(id, at, by))?;
                }
                Ok((n == 1, true))
            })
            .await
        };
        self.cache.revoke_token(id, revoke).await
    }

    async fn has_admin_token(&self) -> Result<bool, StoreError> {
        self.run("has_admin_token", |conn| {
            conn.query_row(
                "SELECT EXISTS (SELECT 1 FROM tokens WHERE role = 'admin' AND revoked_at IS NULL)",
                [],
                |r| r.get(0),
            )
            .map_err(map)
        })
        .await
    }
}
