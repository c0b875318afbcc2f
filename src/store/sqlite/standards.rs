//! Reference standards, stored as their JSON definition.

use async_trait::async_trait;
use rusqlite::params;

use super::SqliteStore;
use super::errors::map;
use super::rows;
use crate::domain::standards::Standard;
use crate::store::{Standards, StoreError};

fn decode(row: &rusqlite::Row<'_>) -> Result<Standard, StoreError> {
    let text: String = row.get("definition").map_err(map)?;
    serde_json::from_str(&text).map_err(|e| StoreError::corrupt("a standard", e))
}

#[async_trait]
impl Standards for SqliteStore {
    async fn put_standard(&self, s: Standard) -> Result<bool, StoreError> {
        self.run("put_standard", move |conn| {
            let definition =
                serde_json::to_string(&s).map_err(|e| StoreError::Refused(e.to_string()))?;
            let existed = rows::first(
                conn,
                "SELECT 1 AS one FROM standards WHERE standard_id = ?1",
                [&s.standard_id],
                |_| Ok(()),
            )?
            .is_some();
            conn.execute(
                "INSERT INTO standards (standard_id, definition, updated_at) VALUES (?1, ?2, ?3) \
                 ON CONFLICT (standard_id) DO UPDATE SET definition = excluded.definition, \
                 updated_at = excluded.updated_at",
                params![s.standard_id, definition, s.updated_at.to_string()],
            )
            .map_err(map)?;
            Ok(!existed)
        })
        .await
    }

    async fn standard(&self, standard_id: String) -> Result<Option<Standard>, StoreError> {
        self.run("standard", move |conn| {
            rows::first(
                conn,
                "SELECT definition FROM standards WHERE standard_id = ?1",
                [standard_id],
                decode,
            )
        })
        .await
    }

    async fn standards(&self) -> Result<Vec<Standard>, StoreError> {
        self.run("standards", |conn| {
            rows::all(
                conn,
                "SELECT definition FROM standards ORDER BY standard_id",
                [],
                decode,
            )
        })
        .await
    }
}
