//! Reference standards, stored as their JSON definition.

use async_trait::async_trait;

use super::PostgresStore;
use super::errors::{decode, map};
use super::rows;
use crate::domain::standards::Standard;
use crate::store::{Standards, StoreError};

fn parse(row: &tokio_postgres::Row) -> Result<Standard, StoreError> {
    let text: &str = rows::get(row, "definition")?;
    serde_json::from_str(text).map_err(|e| decode("definition", e))
}

#[async_trait]
impl Standards for PostgresStore {
    async fn put_standard(&self, s: Standard) -> Result<bool, StoreError> {
        op!(self, "put_standard", |client| {
            let definition =
                serde_json::to_string(&s).map_err(|e| StoreError::Refused(e.to_string()))?;
            let row = client
                .query_one(
                    "INSERT INTO standards (standard_id, definition, updated_at) \
                     VALUES ($1, $2::text::json, $3) \
                     ON CONFLICT (standard_id) DO UPDATE SET definition = excluded.definition, \
                       updated_at = excluded.updated_at \
                     RETURNING (xmax = 0) AS created",
                    &[&s.standard_id, &definition, &s.updated_at.datetime()],
                )
                .await
                .map_err(map)?;
            rows::get(&row, "created")
        })
    }

    async fn standard(&self, standard_id: String) -> Result<Option<Standard>, StoreError> {
        op!(self, "standard", |client| {
            let row = client
                .query_opt(
                    "SELECT definition::text AS definition FROM standards WHERE standard_id = $1",
                    &[&standard_id],
                )
                .await
                .map_err(map)?;
            row.as_ref().map(parse).transpose()
        })
    }

    async fn standards(&self) -> Result<Vec<Standard>, StoreError> {
        op!(self, "standards", |client| {
            let found = client
                .query(
                    "SELECT definition::text AS definition FROM standards ORDER BY standard_id",
                    &[],
                )
                .await
                .map_err(map)?;
            found.iter().map(parse).collect()
        })
    }
}
