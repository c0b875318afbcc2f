//! Sensor types, stored as their JSON definition.

use async_trait::async_trait;
use rusqlite::params;

use super::SqliteStore;
use super::errors::map;
use super::rows;
use crate::domain::sensor_types::SensorType;
use crate::store::{SensorTypes, StoreError};

fn decode(row: &rusqlite::Row<'_>) -> Result<SensorType, StoreError> {
    let text: String = row.get("definition").map_err(map)?;
    serde_json::from_str(&text).map_err(|e| StoreError::corrupt("a sensor type", e))
}

#[async_trait]
impl SensorTypes for SqliteStore {
    async fn put_sensor_type(&self, t: SensorType) -> Result<bool, StoreError> {
        self.run("put_sensor_type", move |conn| {
            let definition =
                serde_json::to_string(&t).map_err(|e| StoreError::Refused(e.to_string()))?;
            let existed = rows::first(
                conn,
                "SELECT 1 AS one FROM sensor_types WHERE type_id = ?1",
                [&t.type_id],
                |_| Ok(()),
            )?
            .is_some();
            conn.execute(
                "INSERT INTO sensor_types (type_id, definition, updated_at) VALUES (?1, ?2, ?3) \
                 ON CONFLICT (type_id) DO UPDATE SET definition = excluded.definition, \
                 updated_at = excluded.updated_at",
                params![t.type_id, definition, t.updated_at.to_string()],
            )
            .map_err(map)?;
            Ok(!existed)
        })
        .await
    }

    async fn sensor_type(&self, type_id: String) -> Result<Option<SensorType>, StoreError> {
        self.run("sensor_type", move |conn| {
            rows::first(
                conn,
                "SELECT definition FROM sensor_types WHERE type_id = ?1",
                [type_id],
                decode,
            )
        })
        .await
    }

    async fn sensor_types(&self) -> Result<Vec<SensorType>, StoreError> {
        self.run("sensor_types", |conn| {
            rows::all(
                conn,
                "SELECT definition FROM sensor_types ORDER BY type_id",
                [],
                decode,
            )
        })
        .await
    }
}
