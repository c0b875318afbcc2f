//! Tokens: only the hash of each secret is stored. Reads go through the
//! token cache ([`crate::store::cache::tokens`]).

use async_trait::async_trait;
use uuid::Uuid;

use super::PostgresStore;
use super::errors::map;
use super::rows::{self, TOKEN_COLUMNS};
use crate::domain::audit::Actor;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::{StoreError, Tokens};

#[async_trait]
impl Tokens for PostgresStore {
    async fn insert_token(&self, t: TokenRecord, by: Actor) -> Result<(), StoreError> {
        act!(self, "insert_token", |client| {
            let tx = client.transaction().await.map_err(map)?;
            tx.execute(
                &format!(
                    "INSERT INTO tokens ({TOKEN_COLUMNS}) VALUES ($1, $2, $3, $4, $5, $6, $7, $8)"
                ),
                &[
                    &t.id,
                    &t.secret_hash,
                    &t.role.as_str(),
                    &t.station_id,
                    &t.label,
                    &t.created_at.datetime(),
                    &t.revoked_at.map(|r| r.datetime()),
                    &t.holder,
                ],
            )
            .await
            .map_err(map)?;
            let event = crate::store::audit::token_created(&t, by);
            super::audit::append(&tx, vec![event]).await?;
            tx.commit().await.map_err(map)?;
            Ok(())
        })
    }

    async fn token(&self, id: Uuid) -> Result<Option<TokenRecord>, StoreError> {
        let read = async {
            op!(self, "token", |client| {
                let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens WHERE id = $1");
                let stmt = client.prepare_cached(&sql).await.map_err(map)?;
                let row = client.query_opt(&stmt, &[&id]).await.map_err(map)?;
                row.as_ref().map(rows::token).transpose()
            })
        };
        self.cache.token(id, read).await
    }

    async fn tokens(&self) -> Result<Vec<TokenRecord>, StoreError> {
        op!(self, "tokens", |client| {
            let sql = format!("SELECT {TOKEN_COLUMNS} FROM tokens ORDER BY id");
            let found = client.query(&sql, &[]).await.map_err(map)?;
            found.iter().map(rows::token).collect()
        })
    }

    async fn revoke_token(&self, id: Uuid, at: Timestamp, by: Actor) -> Result<bool, StoreError> {
        let this = self.clone();
        let revoke = async move {
            act!(this, "revoke_token", |client| {
                let tx = client.transaction().await.map_err(map)?;
                let n = tx
                    .execute(
                        "UPDATE tokens SET revoked_at = $2 WHERE id = $1 AND revoked_at IS NULL",
                        &[&id, &at.datetime()],
                    )
                    .await
                    .map_err(map)?;
                if n == 1 {
                    let event = crate::store::audit::token_revoked(id, at, by);
                    super::audit::append(&tx, vec![event]).await?;
                    tx.commit().await.map_err(map)?;
                }
                Ok(n == 1)
            })
        };
        self.cache.revoke_token(id, revoke).await
    }

    async fn has_admin_token(&self) -> Result<bool, StoreError> {
        op!(self, "has_admin_token", |client| {
            let row = client
            .query_one(
                "SELECT EXISTS (SELECT 1 FROM tokens WHERE role = 'admin' AND revoked_at IS NULL)",
                &[],
            )
            .await
            .map_err(map)?;
            Ok(row.get(0))
        })
    }
}
