//! Records stored as their JSON definition under an id — sensor types,
//! standards, customers, items: one audited upsert and two reads,
//! parameterised by table.

use rusqlite::{Connection, params};
use serde::Serialize;
use serde::de::DeserializeOwned;

use super::errors::map;
use super::{audit, rows};
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
    /// What one record is, for errors.
    pub what: &'static str,
    /// Its kind in the audit trail (`{kind}.put`).
    pub kind: &'static str,
    /// The prefix of its object path in the audit trail (`standards/`).
    pub object: &'static str,
}

fn decode<T: DeserializeOwned>(row: &rusqlite::Row<'_>, what: &str) -> Result<T, StoreError> {
    let text: String = row.get("definition").map_err(map)?;
    serde_json::from_str(&text).map_err(|e| StoreError::corrupt(what, e))
}

/// Creates or replaces the record `id` and appends `{kind}.put` to the
/// audit trail, in the writer's transaction; true when it was created.
pub fn put<T: Serialize>(
    conn: &Connection,
    t: &Table,
    id: &str,
    record: &T,
    updated_at: Timestamp,
    by: Actor,
) -> Result<bool, StoreError> {
    let definition =
        serde_json::to_string(record).map_err(|e| StoreError::Refused(e.to_string()))?;
    let existed = rows::first(
        conn,
        &format!("SELECT 1 AS one FROM {} WHERE {} = ?1", t.name, t.key),
        [id],
        |_| Ok(()),
    )?
    .is_some();
    conn.execute(
        &format!(
            "INSERT INTO {0} ({1}, definition, updated_at) VALUES (?1, ?2, ?3) \
             ON CONFLICT ({1}) DO UPDATE SET definition = excluded.definition, \
             updated_at = excluded.updated_at",
            t.name, t.key
        ),
        params![id, definition, updated_at.to_string()],
    )
    .map_err(map)?;
    let path = format!("{}{id}", t.object);
    let event = crate::store::audit::put(t.kind, path, !existed, record, updated_at, by);
    audit::append(conn, event)?;
    Ok(!existed)
}

/// The record `id`.
pub fn one<T: DeserializeOwned>(
    conn: &Connection,
    t: &Table,
    id: &str,
) -> Result<Option<T>, StoreError> {
    rows::first(
        conn,
        &format!("SELECT definition FROM {} WHERE {} = ?1", t.name, t.key),
        [id],
        |r| decode(r, t.what),
    )
}

/// Every record, in id order.
pub fn all<T: DeserializeOwned>(conn: &Connection, t: &Table) -> Result<Vec<T>, StoreError> {
    rows::all(
        conn,
        &format!("SELECT definition FROM {} ORDER BY {}", t.name, t.key),
        [],
        |r| decode(r, t.what),
    )
}
