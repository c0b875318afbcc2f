//! Reference standards, stored as their JSON definition.

use async_trait::async_trait;

use super::PostgresStore;
use super::definitions::{self, Table};
use crate::domain::audit::Actor;
use crate::domain::standards::Standard;
use crate::store::conditional::{Precondition, Put};
use crate::store::{Standards, StoreError};

const STANDARDS: Table = Table {
    name: "standards",
    key: "standard_id",
    kind: "standard",
    object: "standards/",
};

#[async_trait]
impl Standards for PostgresStore {
    async fn put_standard(
        &self,
        s: Standard,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<Standard>, StoreError> {
        act!(self, "put_standard", |client| {
            let id = s.standard_id.clone();
            definitions::put(
                &mut client,
                &STANDARDS,
                &id,
                |before| s.replacing(before),
                &pre,
                by,
            )
            .await
        })
    }

    async fn standard(&self, standard_id: String) -> Result<Option<Standard>, StoreError> {
        op!(self, "standard", |client| {
            definitions::one(&client, &STANDARDS, &standard_id).await
        })
    }

    async fn standards(&self) -> Result<Vec<Standard>, StoreError> {
        op!(self, "standards", |client| {
            definitions::all(&client, &STANDARDS).await
        })
    }
}
