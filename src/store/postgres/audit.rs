//! The audit trail: each act's entries written to `audit_pending` as the
//! last statements of the act's transaction, without a lock, and chained
//! by the [`seal`](super::seal)er shortly after the commit; every read of
//! the trail seals first.

use std::collections::HashMap;

use async_trait::async_trait;
use deadpool_postgres::{GenericClient, Transaction};
use serde_json::{Map, Value};
use time::OffsetDateTime;

use super::PostgresStore;
use super::errors::map;
use super::rows;
use super::seal;
use crate::domain::audit::{Actor, Entry, Event};
use crate::domain::timestamp::Timestamp;
use crate::store::audit::Submitted;
use crate::store::{Audit, AuditQuery, NewCalibration, StoreError, audit};

const COLUMNS: &str = "seq, at, token_id, role, holder, action, object, change, prev, hash";

fn entry(r: &tokio_postgres::Row) -> Result<Entry, StoreError> {
    let e = rows::event(r)?;
    Ok(Entry {
        seq: rows::get(r, "seq")?,
        at: e.at,
        actor: e.actor,
        action: e.action,
        object: e.object,
        change: e.change,
        prev: rows::get(r, "prev")?,
        hash: rows::get(r, "hash")?,
    })
}

/// Writes `events`, in order, as the act's pending entries: in the
/// transaction `tx`, waiting for no other act; the sealer chains them
/// once `tx` has committed.
pub async fn append(tx: &Transaction<'_>, events: Vec<Event>) -> Result<(), StoreError> {
    if events.is_empty() {
        return Ok(());
    }
    let insert = tx
        .prepare_cached(
            "INSERT INTO audit_pending (at, token_id, role, holder, action, object, change) \
             SELECT at, token_id, role, holder, action, object, change \
             FROM unnest($1::timestamptz[], $2::text[], $3::text[], $4::text[], $5::text[], \
               $6::text[], $7::text[]) WITH ORDINALITY \
             AS u(at, token_id, role, holder, action, object, change, n) ORDER BY n",
        )
        .await
        .map_err(map)?;
    let col = |f: fn(&Event) -> &str| events.iter().map(f).collect::<Vec<&str>>();
    let ats: Vec<OffsetDateTime> = events.iter().map(|e| e.at.datetime()).collect();
    let holders: Vec<Option<&str>> = events.iter().map(|e| e.actor.holder.as_deref()).collect();
    tx.execute(
        &insert,
        &[
            &ats,
            &col(|e| &e.actor.token_id),
            &col(|e| &e.actor.role),
            &holders,
            &col(|e| &e.action),
            &col(|e| &e.object),
            &col(|e| &e.change),
        ],
    )
    .await
    .map_err(map)?;
    Ok(())
}

/// The actor of a submission by `token_id` ([`audit::submitter`]).
pub async fn submitter(client: &impl GenericClient, token_id: &str) -> Result<Actor, StoreError> {
    let found = match uuid::Uuid::try_parse(token_id) {
        Ok(id) => client
            .query_opt("SELECT role, holder FROM tokens WHERE id = $1", &[&id])
            .await
            .map_err(map)?
            .map(|r| Ok::<_, StoreError>((rows::get(&r, "role")?, rows::get(&r, "holder")?)))
            .transpose()?,
        Err(_) => None,
    };
    Ok(audit::submitter(token_id, found))
}

/// A calibration stored, its prepared entry, and whether it became its
/// sensor's latest ([`crate::domain::events::Effect::stored`]).
pub type Written<'a> = (&'a NewCalibration, &'a Submitted, bool);

/// The `calibration.submitted` events of `stored`, in order, each actor
/// looked up once.
pub async fn stored(
    client: &impl GenericClient,
    stored: &[Written<'_>],
) -> Result<Vec<Event>, StoreError> {
    let by: Vec<&str> = stored
        .iter()
        .map(|(n, _, _)| n.submitted_by.as_str())
        .collect();
    let actors = submitters(client, &by).await?;
    entries(&actors, stored)
}

/// The actors of the submitters (token ids) `by`, each looked up once:
/// asked before a batch takes its sensors' rows, so that no round trip
/// for them is made while it holds them.
pub async fn submitters<'a>(
    client: &impl GenericClient,
    by: &[&'a str],
) -> Result<HashMap<&'a str, Actor>, StoreError> {
    let mut actors = HashMap::new();
    for &token_id in by {
        if !actors.contains_key(token_id) {
            actors.insert(token_id, submitter(client, token_id).await?);
        }
    }
    Ok(actors)
}

/// The `calibration.submitted` events of `stored`, by the `actors` of
/// [`submitters`]: built from each prepared entry, with no I/O.
pub fn entries(
    actors: &HashMap<&str, Actor>,
    stored: &[Written<'_>],
) -> Result<Vec<Event>, StoreError> {
    stored
        .iter()
        .map(|&(n, entry, latest)| {
            let by = actors.get(n.submitted_by.as_str()).ok_or_else(|| {
                StoreError::corrupt("audit", "a submitter was not looked up before its entry")
            })?;
            let effect = crate::domain::events::Effect::stored(n.id, latest);
            Ok(entry.event(by.clone(), effect))
        })
        .collect()
}

#[async_trait]
impl Audit for PostgresStore {
    async fn record(&self, events: Vec<Event>) -> Result<(), StoreError> {
        op!(self, "audit_record", |client| {
            let tx = client.transaction().await.map_err(map)?;
            seal::lock(&tx).await?;
            let (head, _) = seal::seal_in(&tx).await?;
            seal::chain(&tx, head, events).await?;
            tx.commit().await.map_err(map)?;
            Ok(())
        })
    }

    async fn audit(&self, q: AuditQuery) -> Result<Vec<Entry>, StoreError> {
        op!(self, "audit", |client| {
            seal::seal_pending(&mut client).await?;
            let limit = i64::try_from(q.limit).unwrap_or(i64::MAX);
            let found = client
                .query(
                    &format!(
                        "SELECT {COLUMNS} FROM audit WHERE seq > $1 \
                         AND ($2::text IS NULL OR object = $2) \
                         AND ($3::text IS NULL OR token_id IN ($3, $7) OR holder = $3) \
                         AND ($4::timestamptz IS NULL OR at >= $4) \
                         AND ($5::timestamptz IS NULL OR at <= $5) \
                         ORDER BY seq LIMIT $6"
                    ),
                    &[
                        &q.after,
                        &q.object,
                        &q.actor,
                        &q.from.map(|t| t.datetime()),
                        &q.to.map(|t| t.datetime()),
                        &limit,
                        &q.actor_token(),
                    ],
                )
                .await
                .map_err(map)?;
            found.iter().map(entry).collect()
        })
    }

    async fn sealed_after(&self, after: i64, limit: usize) -> Result<Vec<Entry>, StoreError> {
        op!(self, "audit_sealed_after", |client| {
            let stmt = client
                .prepare_cached(&format!(
                    "SELECT {COLUMNS} FROM audit WHERE seq > $1 ORDER BY seq LIMIT $2"
                ))
                .await
                .map_err(map)?;
            let limit = i64::try_from(limit).unwrap_or(i64::MAX);
            let found = client.query(&stmt, &[&after, &limit]).await.map_err(map)?;
            found.iter().map(entry).collect()
        })
    }

    async fn audit_head(&self) -> Result<i64, StoreError> {
        op!(self, "audit_head", |client| {
            let row = client
                .query_one("SELECT coalesce(max(seq), 0)::int8 AS head FROM audit", &[])
                .await
                .map_err(map)?;
            rows::get(&row, "head")
        })
    }

    fn trail_grew(&self) -> Option<tokio::sync::watch::Receiver<u64>> {
        Some(self.sealer.sealed())
    }

    async fn unsealed(&self) -> Result<i64, StoreError> {
        op!(self, "audit_unsealed", |client| seal::pending(&client)
            .await)
    }

    async fn configure(&self, settings: Map<String, Value>) -> Result<bool, StoreError> {
        op!(self, "audit_configure", |client| {
            let tx = client.transaction().await.map_err(map)?;
            seal::lock(&tx).await?;
            let (head, _) = seal::seal_in(&tx).await?;
            let event = audit::configured(settings, Timestamp::now());
            let last: Option<String> = tx
                .query_opt(
                    "SELECT change FROM audit WHERE action = 'service.configure' \
                     ORDER BY seq DESC LIMIT 1",
                    &[],
                )
                .await
                .map_err(map)?
                .map(|r| rows::get(&r, "change"))
                .transpose()?;
            if last.as_deref() == Some(event.change.as_str()) {
                return Ok(false);
            }
            seal::chain(&tx, head, vec![event]).await?;
            tx.commit().await.map_err(map)?;
            Ok(true)
        })
    }
}
