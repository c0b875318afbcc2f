//! Reference standards, stored as their JSON definition.

use async_trait::async_trait;

use super::SqliteStore;
use super::definitions::{self, Table};
use crate::domain::audit::Actor;
use crate::domain::standards::Standard;
use crate::store::conditional::{Precondition, Put};
use crate::store::{Standards, StoreError};

const STANDARDS: Table = Table {
    name: "standards",
    key: "standard_id",
    what: "a standard",
    kind: "standard",
    object: "standards/",
};

#[async_trait]
impl Standards for SqliteStore {
    async fn put_standard(
        &self,
        s: Standard,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Standard>, StoreError> {
        self.write("put_standard", move |conn| {
            let id = s.standard_id.clone();
            let put = definitions::put(
                conn,
                &STANDARDS,
                &id,
                |before| s.replacing(before),
                &pre,
                by,
            )?;
            let commit = matches!(put, Put::Written { .. });
            Ok((put, commit))
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
