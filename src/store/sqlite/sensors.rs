//! Sensors: the per-sensor summary kept up to date by every insert, with the
//! status computed at query time.

use rusqlite::{Connection, named_params};

use super::errors::map;
use super::rows;
use crate::domain::status::{DUE_SOON_DAYS, Status};
use crate::domain::timestamp::Timestamp;
use crate::store::{SensorQuery, SensorSummary, StoreError};

/// Sensors in id order, strictly after `after`, of a status.
pub fn list(conn: &Connection, q: &SensorQuery) -> Result<Vec<SensorSummary>, StoreError> {
    let sql = rows::sensor_query(&format!(
        "WHERE (:after IS NULL OR s.sensor_id > :after) \
         AND (:status IS NULL OR {} = :status) \
         AND (:search IS NULL OR instr(lower(s.sensor_id), lower(:search)) > 0) \
         ORDER BY s.sensor_id LIMIT :limit",
        Status::sql(":now", ":soon")
    ));
    let mut stmt = conn.prepare_cached(&sql).map_err(map)?;
    let mut found = stmt
        .query(named_params! {
            ":after": q.after,
            ":status": q.status.map(|s| s.as_str()),
            ":search": q.search,
            ":now": q.now.to_string(),
            ":soon": q.now.plus_seconds(DUE_SOON_DAYS * 86_400).to_string(),
            ":limit": q.limit as i64,
        })
        .map_err(map)?;
    let mut out = Vec::new();
    while let Some(row) = found.next().map_err(map)? {
        out.push(rows::sensor(row)?);
    }
    Ok(out)
}

/// One sensor.
pub fn get(
    conn: &Connection,
    sensor_id: &str,
    now: Timestamp,
) -> Result<Option<SensorSummary>, StoreError> {
    let sql = rows::sensor_query("WHERE s.sensor_id = :id");
    let mut stmt = conn.prepare_cached(&sql).map_err(map)?;
    let mut found = stmt
        .query(named_params! {
            ":id": sensor_id,
            ":now": now.to_string(),
            ":soon": now.plus_seconds(DUE_SOON_DAYS * 86_400).to_string(),
        })
        .map_err(map)?;
    found.next().map_err(map)?.map(rows::sensor).transpose()
}

/// Assigns a type to an existing sensor; whether there was one.
pub fn assign_type(conn: &Connection, sensor_id: &str, type_id: &str) -> Result<bool, StoreError> {
    let n = conn
        .execute(
            "UPDATE sensors SET sensor_type = ?2 WHERE sensor_id = ?1",
            [sensor_id, type_id],
        )
        .map_err(map)?;
    Ok(n == 1)
}
