//! Records stored as their JSON definition under an id — sensor types,
//! standards, customers, items: one audited upsert and two reads,
//! parameterised by table.

use rusqlite::{Connection, params};
use serde::Serialize;
use serde::de::DeserializeOwned;

use super::errors::map;
use super::{audit, rows};
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

/// Creates or replaces the record `id` with `make` of the record it
/// replaces, if `pre` holds for that one, and appends `{kind}.put` to the
/// audit trail — all in the writer's transaction, so nothing is written
/// between the read and the write ([`crate::store::conditional`]).
pub fn put<T: Serialize + DeserializeOwned + Updated>(
    conn: &Connection,
    t: &Table,
    id: &str,
    make: impl FnOnce(Option<T>) -> T,
    pre: &Precondition,
    by: Actor,
) -> Result<Put<T>, StoreError> {
    let before: Option<(String, T)> = rows::first(
        conn,
        &format!("SELECT definition FROM {} WHERE {} = ?1", t.name, t.key),
        [id],
        |r| {
            let text: String = r.get("definition").map_err(map)?;
            let record = serde_json::from_str(&text).map_err(|e| StoreError::corrupt(t.what, e))?;
            Ok((text, record))
        },
    )?;
    let current = before.as_ref().map(|(text, _)| etag_of_text(text));
    if !pre.holds(current.as_deref()) {
        return Ok(Put::Failed { current });
    }
    let created = before.is_none();
    let record = make(before.map(|(_, r)| r));
    let definition =
        serde_json::to_string(&record).map_err(|e| StoreError::Refused(e.to_string()))?;
    conn.execute(
        &format!(
            "INSERT INTO {0} ({1}, definition, updated_at) VALUES (?1, ?2, ?3) \
             ON CONFLICT ({1}) DO UPDATE SET definition = excluded.definition, \
             updated_at = excluded.updated_at",
            t.name, t.key
        ),
        params![id, definition, record.updated_at().to_string()],
    )
    .map_err(map)?;
    let path = format!("{}{id}", t.object);
    let event = crate::store::audit::put(t.kind, path, created, &record, record.updated_at(), by);
    audit::append(conn, event)?;
    Ok(Put::Written {
        created,
        etag: etag_of_text(&definition),
        record,
    })
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
