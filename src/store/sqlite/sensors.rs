//! Sensors: the per-sensor summary kept up to date by every insert, with the
//! status computed at query time. One sensor's reads go through the sensor
//! cache ([`crate::store::cache`]).

use async_trait::async_trait;
use rusqlite::{named_params, params};
use uuid::Uuid;

use super::SqliteStore;
use super::errors::map;
use super::rows;
use crate::domain::audit::Actor;
use crate::domain::status::{DUE_SOON_DAYS, Status};
use crate::domain::timestamp::Timestamp;
use crate::store::{Announced, SensorQuery, SensorSummary, Sensors, StoreError};

#[async_trait]
impl Sensors for SqliteStore {
    async fn sensors(&self, q: SensorQuery) -> Result<Vec<SensorSummary>, StoreError> {
        self.run("sensors", move |conn| {
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
        })
        .await
    }

    async fn sensor(
        &self,
        sensor_id: String,
        now: Timestamp,
    ) -> Result<Option<SensorSummary>, StoreError> {
        self.follow_the_file()?;
        let id = sensor_id.clone();
        let read = self.run("sensor", move |conn| {
            let sql = rows::sensor_query("WHERE s.sensor_id = :id");
            let mut stmt = conn.prepare_cached(&sql).map_err(map)?;
            let mut found = stmt
                .query(named_params! {
                    ":id": id,
                    ":now": now.to_string(),
                    ":soon": now.plus_seconds(DUE_SOON_DAYS * 86_400).to_string(),
                })
                .map_err(map)?;
            found.next().map_err(map)?.map(rows::sensor).transpose()
        });
        self.cache.sensor(&sensor_id, now, read).await
    }

    async fn latest_calibration_id(
        &self,
        sensor_id: String,
    ) -> Result<Option<(Uuid, crate::domain::review::State)>, StoreError> {
        self.follow_the_file()?;
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
        self.follow_the_file()?;
        let id = sensor_id.clone();
        let out = self
            .write("assign_sensor_type", move |conn| {
                let n = conn
                    .execute(
                        "UPDATE sensors SET sensor_type = ?2 WHERE sensor_id = ?1",
                        [&id, &type_id],
                    )
                    .map_err(map)?;
                if n == 1 {
                    let event = crate::store::audit::retyped(&id, &type_id, Timestamp::now(), by);
                    super::audit::append(conn, event)?;
                }
                Ok((n == 1, true))
            })
            .await;
        self.cache.sensor_changed(&sensor_id);
        out
    }

    async fn announced_statuses(&self) -> Result<Vec<Announced>, StoreError> {
        self.run("announced_statuses", |conn| {
            rows::all(
                conn,
                "SELECT sensor_id, status, due_at FROM status_announcements ORDER BY sensor_id",
                [],
                announced,
            )
        })
        .await
    }

    async fn announce_statuses(
        &self,
        now: Vec<Announced>,
        at: Timestamp,
    ) -> Result<usize, StoreError> {
        self.write("announce_statuses", move |conn| {
            let mut n = 0;
            for (sensor, to, due) in now {
                let sql = "SELECT sensor_id, status, due_at FROM status_announcements \
                           WHERE sensor_id = ?1";
                let before = rows::first(conn, sql, [&sensor], announced)?;
                if before
                    .as_ref()
                    .is_some_and(|(_, s, d)| (*s, *d) == (to, due))
                {
                    continue;
                }
                let from = before.filter(|(_, _, d)| *d == due).map(|(_, s, _)| s);
                conn.execute(
                    "INSERT INTO status_announcements (sensor_id, status, due_at) \
                     VALUES (?1, ?2, ?3) ON CONFLICT (sensor_id) DO UPDATE \
                     SET status = excluded.status, due_at = excluded.due_at",
                    params![sensor, to.as_str(), due.to_string()],
                )
                .map_err(map)?;
                let event = crate::store::audit::status_changed(&sensor, from, to, due, at);
                super::audit::append(conn, event)?;
                n += 1;
            }
            Ok((n, n > 0))
        })
        .await
    }
}

/// A row of `status_announcements`.
fn announced(row: &rusqlite::Row<'_>) -> Result<Announced, StoreError> {
    let status: String = row.get("status").map_err(map)?;
    Ok((
        row.get("sensor_id").map_err(map)?,
        Status::parse(&status)
            .ok_or_else(|| StoreError::corrupt("status_announcements.status", status.clone()))?,
        rows::timestamp(row, "due_at")?,
    ))
}
