//! Webhook endpoints and their delivery log ([`crate::store::Webhooks`]).
//! A replica claims an endpoint with a lease taken in one `UPDATE` of the
//! row it picked `FOR UPDATE SKIP LOCKED`, so two replicas looking at once
//! never take the same one and never wait for each other.

use async_trait::async_trait;
use tokio_postgres::Row;
use uuid::Uuid;

use super::PostgresStore;
use super::errors::{decode, map};
use super::rows::{self, get};
use crate::domain::audit::Actor;
use crate::domain::timestamp::Timestamp;
use crate::domain::webhooks::{Definition, Delivery, Endpoint, Outcome, Secret, Secrets};
use crate::store::{Settle, StoreError, Webhooks};

const COLUMNS: &str = "id, url, event_types, sensors, description, secret, previous_secret, \
     previous_until, created_at, updated_at, cursor, failed, next_attempt_at";

const DELIVERY_COLUMNS: &str =
    "event_seq, message_id, attempt, at, outcome, status, error, duration_ms";

fn secret(text: &str, column: &str) -> Result<Secret, StoreError> {
    Secret::parse(text).ok_or_else(|| decode(column, "not a whsec_ secret"))
}

fn endpoint(row: &Row) -> Result<Endpoint, StoreError> {
    let previous = match get::<Option<&str>>(row, "previous_secret")? {
        Some(s) => Some((
            secret(s, "previous_secret")?,
            rows::optional_timestamp(row, "previous_until")?
                .ok_or_else(|| decode("previous_until", "missing"))?,
        )),
        None => None,
    };
    Ok(Endpoint {
        def: Definition {
            webhook_id: get(row, "id")?,
            url: get(row, "url")?,
            event_types: serde_json::from_str(get(row, "event_types")?)
                .map_err(|e| decode("event_types", e))?,
            sensors: serde_json::from_str(get(row, "sensors")?)
                .map_err(|e| decode("sensors", e))?,
            description: get(row, "description")?,
        },
        secrets: Secrets {
            current: secret(get(row, "secret")?, "secret")?,
            previous,
        },
        created_at: rows::timestamp(row, "created_at")?,
        updated_at: rows::timestamp(row, "updated_at")?,
        cursor: get(row, "cursor")?,
        failed: get(row, "failed")?,
        next_attempt_at: rows::timestamp(row, "next_attempt_at")?,
    })
}

fn delivery(row: &Row) -> Result<Delivery, StoreError> {
    let outcome: &str = get(row, "outcome")?;
    Ok(Delivery {
        event_seq: get(row, "event_seq")?,
        message_id: get(row, "message_id")?,
        attempt: get(row, "attempt")?,
        at: rows::timestamp(row, "at")?,
        outcome: Outcome::parse(outcome).ok_or_else(|| decode("outcome", "not an outcome"))?,
        status: get(row, "status")?,
        error: get(row, "error")?,
        duration_ms: get(row, "duration_ms")?,
    })
}

fn list(values: &impl serde::Serialize) -> String {
    serde_json::to_string(values).expect("a list of strings")
}

async fn read(
    c: &impl deadpool_postgres::GenericClient,
    id: &str,
) -> Result<Option<Endpoint>, StoreError> {
    let sql = format!("SELECT {COLUMNS} FROM webhooks WHERE id = $1");
    let row = c.query_opt(&sql, &[&id]).await.map_err(map)?;
    row.as_ref().map(endpoint).transpose()
}

#[async_trait]
impl Webhooks for PostgresStore {
    async fn put_webhook(
        &self,
        def: Definition,
        new_secret: Secret,
        head: i64,
        at: Timestamp,
        by: Actor,
    ) -> Result<(Endpoint, bool), StoreError> {
        act!(self, "put_webhook", |client| {
            let tx = client.transaction().await.map_err(map)?;
            let (types, sensors) = (list(&def.event_types), list(&def.sensors));
            // Inserted, or changed in place: `xmax = 0` only for a new row.
            let created: bool = tx
                .query_one(
                    &format!(
                        "INSERT INTO webhooks ({COLUMNS}) \
                         VALUES ($1, $2, $3, $4, $5, $6, NULL, NULL, $7, $7, $8, 0, $7) \
                         ON CONFLICT (id) DO UPDATE SET url = EXCLUDED.url, \
                         event_types = EXCLUDED.event_types, sensors = EXCLUDED.sensors, \
                         description = EXCLUDED.description, updated_at = EXCLUDED.updated_at \
                         RETURNING (xmax = 0) AS created"
                    ),
                    &[
                        &def.webhook_id,
                        &def.url,
                        &types,
                        &sensors,
                        &def.description,
                        &new_secret.expose(),
                        &at.datetime(),
                        &head,
                    ],
                )
                .await
                .map_err(map)?
                .get("created");
            let secret = created.then_some(&new_secret);
            let event = crate::store::audit::webhook_put(&def, secret, at, by);
            super::audit::append(&tx, vec![event]).await?;
            let stored = read(&tx, &def.webhook_id)
                .await?
                .ok_or_else(|| decode("id", "just written"))?;
            tx.commit().await.map_err(map)?;
            Ok((stored, created))
        })
    }

    async fn webhook(&self, id: String) -> Result<Option<Endpoint>, StoreError> {
        op!(self, "webhook", |client| read(&client, &id).await)
    }

    async fn webhooks(&self) -> Result<Vec<Endpoint>, StoreError> {
        op!(self, "webhooks", |client| {
            let sql = format!("SELECT {COLUMNS} FROM webhooks ORDER BY id");
            let found = client.query(&sql, &[]).await.map_err(map)?;
            found.iter().map(endpoint).collect()
        })
    }

    async fn delete_webhook(
        &self,
        id: String,
        at: Timestamp,
        by: Actor,
    ) -> Result<bool, StoreError> {
        act!(self, "delete_webhook", |client| {
            let tx = client.transaction().await.map_err(map)?;
            let n = tx
                .execute("DELETE FROM webhooks WHERE id = $1", &[&id])
                .await
                .map_err(map)?;
            if n == 1 {
                let event = crate::store::audit::webhook_deleted(&id, at, by);
                super::audit::append(&tx, vec![event]).await?;
            }
            tx.commit().await.map_err(map)?;
            Ok(n == 1)
        })
    }

    async fn rotate_webhook(
        &self,
        id: String,
        new_secret: Secret,
        overlap_until: Timestamp,
        at: Timestamp,
        by: Actor,
    ) -> Result<Option<Endpoint>, StoreError> {
        act!(self, "rotate_webhook", |client| {
            let tx = client.transaction().await.map_err(map)?;
            let n = tx
                .execute(
                    "UPDATE webhooks SET previous_secret = secret, previous_until = $3, \
                     secret = $2, updated_at = $4 WHERE id = $1",
                    &[
                        &id,
                        &new_secret.expose(),
                        &overlap_until.datetime(),
                        &at.datetime(),
                    ],
                )
                .await
                .map_err(map)?;
            if n == 0 {
                return Ok(None);
            }
            let event =
                crate::store::audit::webhook_rotated(&id, &new_secret, overlap_until, at, by);
            super::audit::append(&tx, vec![event]).await?;
            let stored = read(&tx, &id).await?;
            tx.commit().await.map_err(map)?;
            Ok(stored)
        })
    }

    async fn redeliver_webhook(
        &self,
        id: String,
        after: i64,
        at: Timestamp,
        by: Actor,
    ) -> Result<Option<Endpoint>, StoreError> {
        act!(self, "redeliver_webhook", |client| {
            let tx = client.transaction().await.map_err(map)?;
            let n = tx
                .execute(
                    "UPDATE webhooks SET cursor = $2, failed = 0, next_attempt_at = $3, \
                     lease_holder = NULL, lease_until = NULL WHERE id = $1",
                    &[&id, &after, &at.datetime()],
                )
                .await
                .map_err(map)?;
            if n == 0 {
                return Ok(None);
            }
            let event = crate::store::audit::webhook_redelivered(&id, after, at, by);
            super::audit::append(&tx, vec![event]).await?;
            let stored = read(&tx, &id).await?;
            tx.commit().await.map_err(map)?;
            Ok(stored)
        })
    }

    async fn claim_webhook(
        &self,
        head: i64,
        now: Timestamp,
        (holder, until): (Uuid, Timestamp),
    ) -> Result<Option<Endpoint>, StoreError> {
        op!(self, "claim_webhook", |client| {
            let sql = format!(
                "UPDATE webhooks SET lease_holder = $3, lease_until = $4 WHERE id = \
                 (SELECT id FROM webhooks WHERE cursor < $1 AND next_attempt_at <= $2 \
                  AND (lease_until IS NULL OR lease_until < $2) \
                  ORDER BY next_attempt_at, id LIMIT 1 FOR UPDATE SKIP LOCKED) \
                 RETURNING {COLUMNS}"
            );
            let stmt = client.prepare_cached(&sql).await.map_err(map)?;
            let row = client
                .query_opt(&stmt, &[&head, &now.datetime(), &holder, &until.datetime()])
                .await
                .map_err(map)?;
            row.as_ref().map(endpoint).transpose()
        })
    }

    async fn settle_webhook(
        &self,
        id: String,
        holder: Uuid,
        s: Settle,
    ) -> Result<bool, StoreError> {
        op!(self, "settle_webhook", |client| {
            let tx = client.transaction().await.map_err(map)?;
            if let Some(d) = &s.delivery {
                tx.execute(
                    &format!(
                        "INSERT INTO webhook_deliveries (webhook_id, {DELIVERY_COLUMNS}) \
                         SELECT $1, $2, $3, $4, $5, $6, $7, $8, $9 \
                         WHERE EXISTS (SELECT 1 FROM webhooks WHERE id = $1)"
                    ),
                    &[
                        &id,
                        &d.event_seq,
                        &d.message_id,
                        &d.attempt,
                        &d.at.datetime(),
                        &d.outcome.as_str(),
                        &d.status,
                        &d.error,
                        &d.duration_ms,
                    ],
                )
                .await
                .map_err(map)?;
                tx.execute(
                    "DELETE FROM webhook_deliveries WHERE webhook_id = $1 AND id <= \
                     (SELECT id FROM webhook_deliveries WHERE webhook_id = $1 ORDER BY id DESC \
                      LIMIT 1 OFFSET $2)",
                    &[&id, &crate::domain::webhooks::LOG_KEPT],
                )
                .await
                .map_err(map)?;
            }
            let n = tx
                .execute(
                    "UPDATE webhooks SET cursor = $3, failed = $4, next_attempt_at = $5, \
                     lease_holder = CASE WHEN $6::timestamptz IS NULL THEN NULL ELSE lease_holder END, \
                     lease_until = $6 WHERE id = $1 AND lease_holder = $2",
                    &[
                        &id,
                        &holder,
                        &s.cursor,
                        &s.failed,
                        &s.next_attempt_at.datetime(),
                        &s.hold_until.map(|t| t.datetime()),
                    ],
                )
                .await
                .map_err(map)?;
            tx.commit().await.map_err(map)?;
            Ok(n == 1)
        })
    }

    async fn deliveries(&self, id: String, limit: usize) -> Result<Vec<Delivery>, StoreError> {
        op!(self, "deliveries", |client| {
            let sql = format!(
                "SELECT {DELIVERY_COLUMNS} FROM webhook_deliveries WHERE webhook_id = $1 \
                 ORDER BY id DESC LIMIT $2"
            );
            let found = client
                .query(&sql, &[&id, &(limit as i64)])
                .await
                .map_err(map)?;
            found.iter().map(delivery).collect()
        })
    }
}
