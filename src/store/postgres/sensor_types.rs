//! Sensor types, stored as their JSON definition.

use async_trait::async_trait;

use super::PostgresStore;
use super::definitions::{self, Table};
use crate::domain::audit::Actor;
use crate::domain::sensor_types::SensorType;
use crate::store::conditional::{Precondition, Put};
use crate::store::{SensorTypes, StoreError};

const SENSOR_TYPES: Table = Table {
    name: "sensor_types",
    key: "type_id",
    kind: "sensor_type",
    object: "sensor-types/",
};

#[async_trait]
impl SensorTypes for PostgresStore {
    async fn put_sensor_type(
        &self,
        t: SensorType,
        by: Actor,
        pre: Precondition,
    ) -> Result<Put<SensorType>, StoreError> {
        act!(self, "put_sensor_type", |client| {
            let id = t.type_id.clone();
            definitions::put(&mut client, &SENSOR_TYPES, &id, |_| t, &pre, by).await
        })
    }

    async fn sensor_type(&self, type_id: String) -> Result<Option<SensorType>, StoreError> {
        op!(self, "sensor_type", |client| {
            definitions::one(&client, &SENSOR_TYPES, &type_id).await
        })
    }

    async fn sensor_types(&self) -> Result<Vec<SensorType>, StoreError> {
        op!(self, "sensor_types", |client| {
            definitions::all(&client, &SENSOR_TYPES).await
        })
    }
}
