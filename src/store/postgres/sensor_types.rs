//! Sensor types, stored as their JSON definition.

use async_trait::async_trait;

use super::PostgresStore;
use super::errors::{decode, map};
use super::rows;
use crate::domain::sensor_types::SensorType;
use crate::store::{SensorTypes, StoreError};

fn parse(row: &tokio_postgres::Row) -> Result<SensorType, StoreError> {
    let text: &str = rows::get(row, "definition")?;
    serde_json::from_str(text).map_err(|e| decode("definition", e))
}

#[async_trait]
impl SensorTypes for PostgresStore {
    async fn put_sensor_type(&self, t: SensorType) -> Result<bool, StoreError> {
        op!(self, "put_sensor_type", |client| {
            let definition =
                serde_json::to_string(&t).map_err(|e| StoreError::Refused(e.to_string()))?;
            let row = client
            .query_one(
                "INSERT INTO sensor_types (type_id, definition, updated_at) VALUES ($1, $2::text::json, $3) \
                 ON CONFLICT (type_id) DO UPDATE SET definition = excluded.definition, \
                   updated_at = excluded.updated_at \
                 RETURNING (xmax = 0) AS created",
                &[&t.type_id, &definition, &t.updated_at.datetime()],
            )
            .await
            .map_err(map)?;
            rows::get(&row, "created")
        })
    }

    async fn sensor_type(&self, type_id: String) -> Result<Option<SensorType>, StoreError> {
        op!(self, "sensor_type", |client| {
            let row = client
                .query_opt(
                    "SELECT definition::text AS definition FROM sensor_types WHERE type_id = $1",
                    &[&type_id],
                )
                .await
                .map_err(map)?;
            row.as_ref().map(parse).transpose()
        })
    }

    async fn sensor_types(&self) -> Result<Vec<SensorType>, StoreError> {
        op!(self, "sensor_types", |client| {
            let found = client
                .query(
                    "SELECT definition::text AS definition FROM sensor_types ORDER BY type_id",
                    &[],
                )
                .await
                .map_err(map)?;
            found.iter().map(parse).collect()
        })
    }
}
