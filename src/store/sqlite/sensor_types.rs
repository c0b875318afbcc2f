//! Sensor types, stored as their JSON definition.

use async_trait::async_trait;

use super::SqliteStore;
use super::definitions::{self, Table};
use crate::domain::audit::Actor;
use crate::domain::sensor_types::SensorType;
use crate::store::conditional::{Precondition, Put};
use crate::store::{SensorTypes, StoreError};

const SENSOR_TYPES: Table = Table {
    name: "sensor_types",
    key: "type_id",
    what: "a sensor type",
    kind: "sensor_type",
    object: "sensor-types/",
};

#[async_trait]
impl SensorTypes for SqliteStore {
    async fn put_sensor_type(
        &self,
        t: SensorType,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<SensorType>, StoreError> {
        self.write("put_sensor_type", move |conn| {
            let id = t.type_id.clone();
            let put = definitions::put(conn, &SENSOR_TYPES, &id, |_| t, &pre, by)?;
            let commit = matches!(put, Put::Written { .. });
            Ok((put, commit))
        })
        .await
    }

    async fn sensor_type(&self, type_id: String) -> Result<Option<SensorType>, StoreError> {
        self.run("sensor_type", move |conn| {
            definitions::one(conn, &SENSOR_TYPES, &type_id)
        })
        .await
    }

    async fn sensor_types(&self) -> Result<Vec<SensorType>, StoreError> {
        self.run("sensor_types", |conn| definitions::all(conn, &SENSOR_TYPES))
            .await
    }
}
