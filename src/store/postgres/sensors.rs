//! Sensors: the per-sensor summary kept up to date by every insert, with the
//! status computed at query time. One sensor's reads go through the sensor
//! cache ([`crate::store::cache`]).

use async_trait::async_trait;
use uuid::Uuid;

use super::PostgresStore;
use super::errors::map;
use super::rows;
use crate::domain::audit::Actor;
use crate::domain::status::{DUE_SOON_DAYS, Status};
use crate::domain::timestamp::Timestamp;
use crate::store::{Announced, SensorQuery, SensorSummary, Sensors, StoreError};

#[async_trait]
impl Sensors for PostgresStore {
    async fn sensors(&self, q: SensorQuery) -> Result<Vec<SensorSummary>, StoreError> {
        op!(self, "sensors", |client| {
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
        })
    }

    async fn sensor(
        &self,
        sensor_id: String,
        now: Timestamp,
    ) -> Result<Option<SensorSummary>, StoreError> {
        let read = async {
            op!(self, "sensor", |client| {
                let sql = rows::sensor_query("WHERE s.sensor_id = $3");
                let stmt = client.prepare_cached(&sql).await.map_err(map)?;
                let soon = now.plus_seconds(DUE_SOON_DAYS * 86_400);
                let row = client
                    .query_opt(&stmt, &[&now.datetime(), &soon.datetime(), &sensor_id])
                    .await
                    .map_err(map)?;
                row.as_ref().map(rows::sensor).transpose()
            })
        };
        self.cache.sensor(&sensor_id, now, read).await
    }

    async fn latest_calibration_id(
        &self,
        sensor_id: String,
    ) -> Result<Option<(Uuid, crate::domain::review::State)>, StoreError> {
        if let Some(latest) = self.cache.latest_calibration_id(&sensor_id) {
            return Ok(Some(latest));
        }
        Ok(self
            .sensor(sensor_id, Timestamp::now())
            .await?
            .map(|s| (s.latest.id, s.latest.state)))
    }

    /// Drops the sensor's cached summary, whatever the database answered.
    async fn assign_sensor_type(
        &self,
        sensor_id: String,
        type_id: String,
        by: Actor,
    ) -> Result<bool, StoreError> {
        let out = act!(self, "assign_sensor_type", |client| {
            let tx = client.transaction().await.map_err(map)?;
            let n = tx
                .execute(
                    "UPDATE sensors SET sensor_type = $2 WHERE sensor_id = $1",
                    &[&sensor_id, &type_id],
                )
                .await
                .map_err(map)?;
            if n == 1 {
                let event =
                    crate::store::audit::retyped(&sensor_id, &type_id, Timestamp::now(), by);
                super::audit::append(&tx, vec![event]).await?;
                tx.commit().await.map_err(map)?;
            }
            Ok(n == 1)
        });
        self.cache.sensor_changed(&sensor_id);
        out
    }

    async fn announced_statuses(&self) -> Result<Vec<Announced>, StoreError> {
        op!(self, "announced_statuses", |client| {
            let found = client
                .query(
                    "SELECT sensor_id, status, due_at FROM status_announcements ORDER BY sensor_id",
                    &[],
                )
                .await
                .map_err(map)?;
            found.iter().map(announced).collect()
        })
    }

    /// The row of a sensor already announced is locked first, so the
    /// `from` read is the one replaced; a sensor announced for the first
    /// time by two replicas at once is inserted by one, and the other's
    /// upsert then finds nothing different.
    async fn announce_statuses(
        &self,
        now: Vec<Announced>,
        at: Timestamp,
    ) -> Result<usize, StoreError> {
        act!(self, "announce_statuses", |client| {
            let tx = client.transaction().await.map_err(map)?;
            let mut events = Vec::new();
            for (sensor, to, due) in now {
                let before = tx
                    .query_opt(
                        "SELECT sensor_id, status, due_at FROM status_announcements \
                         WHERE sensor_id = $1 FOR UPDATE",
                        &[&sensor],
                    )
                    .await
                    .map_err(map)?
                    .as_ref()
                    .map(announced)
                    .transpose()?;
                let changed = tx
                    .query_opt(
                        "INSERT INTO status_announcements (sensor_id, status, due_at) \
                         VALUES ($1, $2, $3) ON CONFLICT (sensor_id) DO UPDATE \
                         SET status = EXCLUDED.status, due_at = EXCLUDED.due_at \
                         WHERE (status_announcements.status, status_announcements.due_at) \
                         IS DISTINCT FROM (EXCLUDED.status, EXCLUDED.due_at) RETURNING 1",
                        &[&sensor, &to.as_str(), &due.datetime()],
                    )
                    .await
                    .map_err(map)?;
                if changed.is_some() {
                    let from = before.filter(|(_, _, d)| *d == due).map(|(_, s, _)| s);
                    events.push(crate::store::audit::status_changed(
                        &sensor, from, to, due, at,
                    ));
                }
            }
            let n = events.len();
            if n > 0 {
                super::audit::append(&tx, events).await?;
            }
            tx.commit().await.map_err(map)?;
            Ok(n)
        })
    }
}

/// A row of `status_announcements`.
fn announced(row: &tokio_postgres::Row) -> Result<Announced, StoreError> {
    let status: &str = rows::get(row, "status")?;
    Ok((
        rows::get(row, "sensor_id")?,
        Status::parse(status)
            .ok_or_else(|| StoreError::corrupt("status_announcements.status", status.to_owned()))?,
        rows::timestamp(row, "due_at")?,
    ))
}
