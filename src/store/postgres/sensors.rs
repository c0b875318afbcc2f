//! Sensors: the per-sensor summary kept up to date by every insert, with the
//! status computed at query time.

use deadpool_postgres::Object;

use super::errors::map;
use super::rows;
use crate::domain::status::{DUE_SOON_DAYS, Status};
use crate::domain::timestamp::Timestamp;
use crate::store::{SensorQuery, SensorSummary, StoreError};

/// Sensors in id order, strictly after `after`, of a status, found by a part
/// of their id.
pub async fn list(client: &Object, q: &SensorQuery) -> Result<Vec<SensorSummary>, StoreError> {
    let sql = rows::sensor_query(&format!(
        "WHERE ($3::text IS NULL OR s.sensor_id > $3) \
         AND ($4::text IS NULL OR {} = $4) \
         AND ($5::text IS NULL OR strpos(lower(s.sensor_id), lower($5)) > 0) \
         ORDER BY s.sensor_id LIMIT $6",
        Status::sql("$1", "$2")
    ));
    let stmt = client.prepare_cached(&sql).await.map_err(map)?;
    let soon = q.now.plus_seconds(DUE_SOON_DAYS * 86_400);
    let found = client
        .query(
            &stmt,
            &[
                &q.now.datetime(),
                &soon.datetime(),
                &q.after,
                &q.status.map(|s| s.as_str()),
                &q.search,
                &(q.limit as i64),
            ],
        )
        .await
        .map_err(map)?;
    found.iter().map(rows::sensor).collect()
}

/// One sensor.
pub async fn get(
    client: &Object,
    sensor_id: &str,
    now: Timestamp,
) -> Result<Option<SensorSummary>, StoreError> {
    let sql = rows::sensor_query("WHERE s.sensor_id = $3");
    let stmt = client.prepare_cached(&sql).await.map_err(map)?;
    let soon = now.plus_seconds(DUE_SOON_DAYS * 86_400);
    let row = client
        .query_opt(&stmt, &[&now.datetime(), &soon.datetime(), &sensor_id])
        .await
        .map_err(map)?;
    row.as_ref().map(rows::sensor).transpose()
}

/// Assigns a type to an existing sensor; whether there was one.
pub async fn assign_type(
    client: &Object,
    sensor_id: &str,
    type_id: &str,
) -> Result<bool, StoreError> {
    let n = client
        .execute(
            "UPDATE sensors SET sensor_type = $2 WHERE sensor_id = $1",
            &[&sensor_id, &type_id],
        )
        .await
        .map_err(map)?;
    Ok(n == 1)
}
