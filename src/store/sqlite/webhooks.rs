//! Webhook endpoints and their delivery log ([`crate::store::Webhooks`]):
//! every write through the writer, leases compared as canonical time text.

use async_trait::async_trait;
use rusqlite::{Connection, OptionalExtension, Row, params};
use uuid::Uuid;

use super::errors::map;
use super::rows;
use super::{SqliteStore, audit};
use crate::domain::audit::Actor;
use crate::domain::timestamp::Timestamp;
use crate::domain::webhooks::{Definition, Delivery, Endpoint, Outcome, Secret, Secrets};
use crate::store::{Settle, StoreError, Webhooks};

const COLUMNS: &str = "id, url, event_types, sensors, description, secret, previous_secret, \
     previous_until, created_at, updated_at, cursor, failed, next_attempt_at";

const DELIVERY_COLUMNS: &str =
    "event_seq, message_id, attempt, at, outcome, status, error, duration_ms";

fn corrupt(column: &str, e: impl Into<crate::store::BoxError>) -> StoreError {
    StoreError::corrupt(format!("webhooks column `{column}`"), e)
}

fn secret(text: String, column: &str) -> Result<Secret, StoreError> {
    Secret::parse(&text).ok_or_else(|| corrupt(column, "not a whsec_ secret"))
}

fn endpoint(row: &Row<'_>) -> Result<Endpoint, StoreError> {
    let text = |c: &str| row.get::<_, String>(c).map_err(map);
    let previous = match row
        .get::<_, Option<String>>("previous_secret")
        .map_err(map)?
    {
        Some(s) => Some((
            secret(s, "previous_secret")?,
            rows::optional_timestamp(row, "previous_until")?
                .ok_or_else(|| corrupt("previous_until", "missing"))?,
        )),
        None => None,
    };
    Ok(Endpoint {
        def: Definition {
            webhook_id: text("id")?,
            url: text("url")?,
            event_types: serde_json::from_str(&text("event_types")?)
                .map_err(|e| corrupt("event_types", e))?,
            sensors: serde_json::from_str(&text("sensors")?).map_err(|e| corrupt("sensors", e))?,
            description: row.get("description").map_err(map)?,
        },
        secrets: Secrets {
            current: secret(text("secret")?, "secret")?,
            previous,
        },
        created_at: rows::timestamp(row, "created_at")?,
        updated_at: rows::timestamp(row, "updated_at")?,
        cursor: row.get("cursor").map_err(map)?,
        failed: row.get("failed").map_err(map)?,
        next_attempt_at: rows::timestamp(row, "next_attempt_at")?,
    })
}

fn delivery(row: &Row<'_>) -> Result<Delivery, StoreError> {
    let outcome: String = row.get("outcome").map_err(map)?;
    Ok(Delivery {
        event_seq: row.get("event_seq").map_err(map)?,
        message_id: row.get("message_id").map_err(map)?,
        attempt: row.get("attempt").map_err(map)?,
        at: rows::timestamp(row, "at")?,
        outcome: Outcome::parse(&outcome).ok_or_else(|| corrupt("outcome", outcome.clone()))?,
        status: row.get("status").map_err(map)?,
        error: row.get("error").map_err(map)?,
        duration_ms: row.get("duration_ms").map_err(map)?,
    })
}

fn read(conn: &Connection, id: &str) -> Result<Option<Endpoint>, StoreError> {
    let sql = format!("SELECT {COLUMNS} FROM webhooks WHERE id = ?1");
    rows::first(conn, &sql, [id], endpoint)
}

fn log(conn: &Connection, id: &str, d: &Delivery) -> Result<(), StoreError> {
    conn.execute(
        &format!(
            "INSERT INTO webhook_deliveries (webhook_id, {DELIVERY_COLUMNS}) \
             SELECT ?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9 \
             WHERE EXISTS (SELECT 1 FROM webhooks WHERE id = ?1)"
        ),
        params![
            id,
            d.event_seq,
            d.message_id,
            d.attempt,
            d.at.to_string(),
            d.outcome.as_str(),
            d.status,
            d.error,
            d.duration_ms
        ],
    )
    .map_err(map)?;
    // Keep the newest LOG_KEPT.
    conn.execute(
        "DELETE FROM webhook_deliveries WHERE webhook_id = ?1 AND id <= \
         (SELECT id FROM webhook_deliveries WHERE webhook_id = ?1 ORDER BY id DESC \
          LIMIT 1 OFFSET ?2)",
        params![id, crate::domain::webhooks::LOG_KEPT],
    )
    .map_err(map)?;
    Ok(())
}

/// After an `UPDATE` of endpoint `id` that changed `n` rows: none, and
/// nothing kept, when there is no such endpoint; else `event` appended and
/// the endpoint as it now is.
fn recorded(
    conn: &Connection,
    id: &str,
    n: usize,
    event: impl FnOnce() -> crate::domain::audit::Event,
) -> Result<(Option<Endpoint>, bool), StoreError> {
    if n == 0 {
        return Ok((None, false));
    }
    super::audit::append(conn, event())?;
    Ok((read(conn, id)?, true))
}

fn list(values: &impl serde::Serialize) -> String {
    serde_json::to_string(values).expect("a list of strings")
}

#[async_trait]
impl Webhooks for SqliteStore {
    async fn put_webhook(
        &self,
        def: Definition,
        new_secret: Secret,
        head: i64,
        at: Timestamp,
        by: Actor,
    ) -> Result<(Endpoint, bool), StoreError> {
        self.write("put_webhook", move |conn| {
            let id = def.webhook_id.clone();
            let changed = conn
                .execute(
                    "UPDATE webhooks SET url = ?2, event_types = ?3, sensors = ?4, \
                     description = ?5, updated_at = ?6 WHERE id = ?1",
                    params![
                        id,
                        def.url,
                        list(&def.event_types),
                        list(&def.sensors),
                        def.description,
                        at.to_string()
                    ],
                )
                .map_err(map)?;
            let created = changed == 0;
            if created {
                conn.execute(
                    &format!("INSERT INTO webhooks ({COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, NULL, NULL, ?7, ?7, ?8, 0, ?7)"),
                    params![
                        id,
                        def.url,
                        list(&def.event_types),
                        list(&def.sensors),
                        def.description,
                        new_secret.expose(),
                        at.to_string(),
                        head
                    ],
                )
                .map_err(map)?;
            }
            let secret = created.then_some(&new_secret);
            audit::append(conn, crate::store::audit::webhook_put(&def, secret, at, by))?;
            let stored = read(conn, &id)?.ok_or_else(|| corrupt("id", "just written"))?;
            Ok(((stored, created), true))
        })
        .await
    }

    async fn webhook(&self, id: String) -> Result<Option<Endpoint>, StoreError> {
        self.run("webhook", move |conn| read(conn, &id)).await
    }

    async fn webhooks(&self) -> Result<Vec<Endpoint>, StoreError> {
        self.run("webhooks", |conn| {
            let sql = format!("SELECT {COLUMNS} FROM webhooks ORDER BY id");
            rows::all(conn, &sql, [], endpoint)
        })
        .await
    }

    async fn delete_webhook(
        &self,
        id: String,
        at: Timestamp,
        by: Actor,
    ) -> Result<bool, StoreError> {
        self.write("delete_webhook", move |conn| {
            conn.execute(
                "DELETE FROM webhook_deliveries WHERE webhook_id = ?1",
                [&id],
            )
            .map_err(map)?;
            let n = conn
                .execute("DELETE FROM webhooks WHERE id = ?1", [&id])
                .map_err(map)?;
            if n == 1 {
                audit::append(conn, crate::store::audit::webhook_deleted(&id, at, by))?;
            }
            Ok((n == 1, true))
        })
        .await
    }

    async fn rotate_webhook(
        &self,
        id: String,
        new_secret: Secret,
        overlap_until: Timestamp,
        at: Timestamp,
        by: Actor,
    ) -> Result<Option<Endpoint>, StoreError> {
        self.write("rotate_webhook", move |conn| {
            let n = conn
                .execute(
                    "UPDATE webhooks SET previous_secret = secret, previous_until = ?3, \
                     secret = ?2, updated_at = ?4 WHERE id = ?1",
                    params![
                        id,
                        new_secret.expose(),
                        overlap_until.to_string(),
                        at.to_string()
                    ],
                )
                .map_err(map)?;
            let event =
                || crate::store::audit::webhook_rotated(&id, &new_secret, overlap_until, at, by);
            recorded(conn, &id, n, event)
        })
        .await
    }

    async fn redeliver_webhook(
        &self,
        id: String,
        after: i64,
        at: Timestamp,
        by: Actor,
    ) -> Result<Option<Endpoint>, StoreError> {
        self.write("redeliver_webhook", move |conn| {
            let n = conn
                .execute(
                    "UPDATE webhooks SET cursor = ?2, failed = 0, next_attempt_at = ?3, \
                     lease_holder = NULL, lease_until = NULL WHERE id = ?1",
                    params![id, after, at.to_string()],
                )
                .map_err(map)?;
            recorded(conn, &id, n, || {
                crate::store::audit::webhook_redelivered(&id, after, at, by)
            })
        })
        .await
    }

    async fn claim_webhook(
        &self,
        head: i64,
        now: Timestamp,
        (holder, until): (Uuid, Timestamp),
    ) -> Result<Option<Endpoint>, StoreError> {
        self.write("claim_webhook", move |conn| {
            let now = now.to_string();
            let id: Option<String> = conn
                .query_row(
                    "UPDATE webhooks SET lease_holder = ?3, lease_until = ?4 WHERE id = \
                     (SELECT id FROM webhooks WHERE cursor < ?1 AND next_attempt_at <= ?2 \
                      AND (lease_until IS NULL OR lease_until < ?2) \
                      ORDER BY next_attempt_at, id LIMIT 1) RETURNING id",
                    params![head, now, holder.to_string(), until.to_string()],
                    |r| r.get(0),
                )
                .optional()
                .map_err(map)?;
            match id {
                Some(id) => Ok((read(conn, &id)?, true)),
                None => Ok((None, false)),
            }
        })
        .await
    }

    async fn settle_webhook(
        &self,
        id: String,
        holder: Uuid,
        s: Settle,
    ) -> Result<bool, StoreError> {
        self.write("settle_webhook", move |conn| {
            if let Some(d) = &s.delivery {
                log(conn, &id, d)?;
            }
            let n = conn
                .execute(
                    "UPDATE webhooks SET cursor = ?3, failed = ?4, next_attempt_at = ?5, \
                     lease_holder = CASE WHEN ?6 IS NULL THEN NULL ELSE lease_holder END, \
                     lease_until = ?6 WHERE id = ?1 AND lease_holder = ?2",
                    params![
                        id,
                        holder.to_string(),
                        s.cursor,
                        s.failed,
                        s.next_attempt_at.to_string(),
                        s.hold_until.map(|t| t.to_string())
                    ],
                )
                .map_err(map)?;
            Ok((n == 1, true))
        })
        .await
    }

    async fn deliveries(&self, id: String, limit: usize) -> Result<Vec<Delivery>, StoreError> {
        self.run("deliveries", move |conn| {
            let sql = format!(
                "SELECT {DELIVERY_COLUMNS} FROM webhook_deliveries WHERE webhook_id = ?1 \
                 ORDER BY id DESC LIMIT ?2"
            );
            rows::all(conn, &sql, params![id, limit as i64], delivery)
        })
        .await
    }
}
