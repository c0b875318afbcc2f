//! Reference standards, stored as their JSON definition.

use async_trait::async_trait;

use super::SqliteStore;
use super::definitions::{self, Table};
use crate::domain::standards::Standard;
use crate::store::{Standards, StoreError};

const STANDARDS: Table = Table {
    name: "standards",
    key: "standard_id",
    what: "a standard",
};

#[async_trait]
impl Standards for SqliteStore {
    async fn put_standard(&self, s: Standard) -> Result<bool, StoreError> {
        self.run("put_standard", move |conn| {
            definitions::put(
                conn,
                &STANDARDS,
                &s.standard_id,
                &s,
                &s.updated_at.to_string(),
            )
        })
        .await
    }

    async fn standard(&self, standard_id: String) -> Result<Option<Standard>, StoreError> {
        self.run("standard", move |conn| {
            definitions::one(conn, &STANDARDS, &standard_id)
        })
        .await
    }

    async fn standards(&self) -> Result<Vec<Standard>, StoreError> {
        self.run("standards", |conn| definitions::all(conn, &STANDARDS))
            .await
    }
}
