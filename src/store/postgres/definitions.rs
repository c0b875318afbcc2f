//! Records stored as their JSON definition under an id — sensor types,
//! standards, customers, items: one audited upsert and two reads,
//! parameterised by table.

use deadpool_postgres::Object;
use serde::Serialize;
use serde::de::DeserializeOwned;

use super::errors::{decode, map};
use super::rows;
use crate::domain::audit::Actor;
use crate::domain::timestamp::Timestamp;
use crate::store::StoreError;

/// A table of definitions: its name and its key column (fixed strings,
/// never input).
pub struct Table {
    /// The table.
    pub name: &'static str,
    /// Its primary key.
    pub key: &'static str,
    /// Its kind in the audit trail (`{kind}.put`).
    pub kind: &'static str,
    /// The prefix of its object path in the audit trail (`standards/`).
    pub object: &'static str,
}

fn parse<T: DeserializeOwned>(row: &tokio_postgres::Row) -> Result<T, StoreError> {
    let text: &str = rows::get(row, "definition")?;
    serde_json::from_str(text).map_err(|e| decode("definition", e))
}

/// Creates or replaces the record `id` and appends `{kind}.put` to the
/// audit trail, in one transaction; true when it was created.
pub async fn put<T: Serialize>(
    client: &mut Object,
    t: &Table,
    id: &str,
    record: &T,
    updated_at: Timestamp,
    by: Actor,
) -> Result<bool, StoreError> {
    let definition =
        serde_json::to_string(record).map_err(|e| StoreError::Refused(e.to_string()))?;
    let tx = client.transaction().await.map_err(map)?;
    let row = tx
        .query_one(
            &format!(
                "INSERT INTO {0} ({1}, definition, updated_at) VALUES ($1, $2::text::json, $3) \
                 ON CONFLICT ({1}) DO UPDATE SET definition = excluded.definition, \
                 updated_at = excluded.updated_at RETURNING (xmax = 0) AS created",
                t.name, t.key
            ),
            &[&id, &definition, &updated_at.datetime()],
        )
        .await
        .map_err(map)?;
    let created: bool = rows::get(&row, "created")?;
    let path = format!("{}{id}", t.object);
    let event = crate::store::audit::put(t.kind, path, created, record, updated_at, by);
    super::audit::append(&tx, vec![event]).await?;
    tx.commit().await.map_err(map)?;
    Ok(created)
}

/// The record `id`.
pub async fn one<T: DeserializeOwned>(
    client: &Object,
    t: &Table,
    id: &str,
) -> Result<Option<T>, StoreError> {
    let row = client
        .query_opt(
            &format!(
                "SELECT definition::text AS definition FROM {} WHERE {} = $1",
                t.name, t.key
            ),
            &[&id],
        )
        .await
        .map_err(map)?;
    row.as_ref().map(parse).transpose()
}

/// Every record, in id order.
pub async fn all<T: DeserializeOwned>(client: &Object, t: &Table) -> Result<Vec<T>, StoreError> {
    let found = client
        .query(
            &format!(
                "SELECT definition::text AS definition FROM {} ORDER BY {}",
                t.name, t.key
            ),
            &[],
        )
        .await
        .map_err(map)?;
    found.iter().map(parse).collect()
}
