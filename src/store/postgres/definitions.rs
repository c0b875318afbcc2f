//! Records stored as their JSON definition under an id — sensor types,
//! standards, customers, items: one audited upsert and two reads,
//! parameterised by table.

use deadpool_postgres::Object;
use serde::Serialize;
use serde::de::DeserializeOwned;

use super::errors::{decode, map};
use super::rows;
use crate::domain::audit::Actor;
use crate::store::StoreError;
use crate::store::conditional::{Precondition, Put, Updated, etag_of_text};

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

/// Creates or replaces the record `id` with `make` of the record it
/// replaces, if `pre` holds for that one, and appends `{kind}.put` to the
/// audit trail, in one transaction under an advisory lock on the record
/// (`{table}/{id}`): two replicas writing one record at once apply one
/// after the other, each reading what the other wrote
/// ([`crate::store::conditional`]).
pub async fn put<T: Serialize + DeserializeOwned + Updated>(
    client: &mut Object,
    t: &Table,
    id: &str,
    make: impl FnOnce(Option<T>) -> T,
    pre: &Precondition,
    by: Actor,
) -> Result<Put<T>, StoreError> {
    let tx = client.transaction().await.map_err(map)?;
    tx.execute(
        "SELECT pg_advisory_xact_lock(hashtextextended($1, 0))",
        &[&format!("{}/{id}", t.name)],
    )
    .await
    .map_err(map)?;
    let before = tx
        .query_opt(
            &format!(
                "SELECT definition::text AS definition FROM {} WHERE {} = $1",
                t.name, t.key
            ),
            &[&id],
        )
        .await
        .map_err(map)?;
    let before: Option<(String, T)> = match before {
        None => None,
        Some(row) => {
            let text: String = rows::get(&row, "definition")?;
            let record = serde_json::from_str(&text).map_err(|e| decode("definition", e))?;
            Some((text, record))
        }
    };
    let current = before.as_ref().map(|(text, _)| etag_of_text(text));
    if !pre.holds(current.as_deref()) {
        return Ok(Put::Failed { current });
    }
    let created = before.is_none();
    let record = make(before.map(|(_, r)| r));
    let definition =
        serde_json::to_string(&record).map_err(|e| StoreError::Refused(e.to_string()))?;
    tx.execute(
        &format!(
            "INSERT INTO {0} ({1}, definition, updated_at) VALUES ($1, $2::text::json, $3) \
             ON CONFLICT ({1}) DO UPDATE SET definition = excluded.definition, \
             updated_at = excluded.updated_at",
            t.name, t.key
        ),
        &[&id, &definition, &record.updated_at().datetime()],
    )
    .await
    .map_err(map)?;
    let path = format!("{}{id}", t.object);
    let event = crate::store::audit::put(t.kind, path, created, &record, record.updated_at(), by);
    super::audit::append(&tx, vec![event]).await?;
    tx.commit().await.map_err(map)?;
    Ok(Put::Written {
        created,
        etag: etag_of_text(&definition),
        record,
    })
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
