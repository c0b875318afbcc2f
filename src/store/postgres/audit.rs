//! The audit trail: entries appended as the last statements of each act's
//! transaction, under the table's `EXCLUSIVE` lock held until the commit —
//! so replicas writing at once append one after the other, each reading the
//! head its predecessor committed. Taken last, after every row lock of the
//! act, the lock cannot close a cycle of waits with another act.

use async_trait::async_trait;
use deadpool_postgres::{GenericClient, Transaction};
use serde_json::{Map, Value};
use time::OffsetDateTime;

use super::PostgresStore;
use super::errors::map;
use super::rows;
use crate::domain::audit::{Actor, Entry, Event};
use crate::domain::timestamp::Timestamp;
use crate::store::{Audit, AuditQuery, StoreError, audit};

const COLUMNS: &str = "seq, at, token_id, role, holder, action, object, change, prev, hash";

fn entry(r: &tokio_postgres::Row) -> Result<Entry, StoreError> {
    Ok(Entry {
        seq: rows::get(r, "seq")?,
        at: Timestamp::from_datetime(rows::get::<OffsetDateTime>(r, "at")?),
        actor: Actor {
            token_id: rows::get(r, "token_id")?,
            role: rows::get(r, "role")?,
            holder: rows::get(r, "holder")?,
        },
        action: rows::get(r, "action")?,
        object: rows::get(r, "object")?,
        change: rows::get(r, "change")?,
        prev: rows::get(r, "prev")?,
        hash: rows::get(r, "hash")?,
    })
}

/// Appends `events`, in order, after the last entry: the last thing the
/// transaction `tx` does before its commit.
pub async fn append(tx: &Transaction<'_>, events: Vec<Event>) -> Result<(), StoreError> {
    if events.is_empty() {
        return Ok(());
    }
    tx.batch_execute("LOCK TABLE audit IN EXCLUSIVE MODE")
        .await
        .map_err(map)?;
    let last = tx
        .query_opt("SELECT seq, hash FROM audit ORDER BY seq DESC LIMIT 1", &[])
        .await
        .map_err(map)?;
    let mut head: Option<(i64, String)> = match last {
        Some(r) => Some((rows::get(&r, "seq")?, rows::get(&r, "hash")?)),
        None => None,
    };
    let mut entries = Vec::with_capacity(events.len());
    for event in events {
        let e = Entry::chain(head.as_ref().map(|(s, h)| (*s, h.as_str())), event);
        head = Some((e.seq, e.hash.clone()));
        entries.push(e);
    }
    let insert = tx
        .prepare_cached(&format!(
            "INSERT INTO audit ({COLUMNS}) SELECT * FROM unnest($1::int8[], $2::timestamptz[], \
             $3::text[], $4::text[], $5::text[], $6::text[], $7::text[], $8::text[], $9::text[], \
             $10::text[])"
        ))
        .await
        .map_err(map)?;
    let col = |f: fn(&Entry) -> &str| entries.iter().map(f).collect::<Vec<&str>>();
    let seqs: Vec<i64> = entries.iter().map(|e| e.seq).collect();
    let ats: Vec<OffsetDateTime> = entries.iter().map(|e| e.at.datetime()).collect();
    let holders: Vec<Option<&str>> = entries.iter().map(|e| e.actor.holder.as_deref()).collect();
    tx.execute(
        &insert,
        &[
            &seqs,
            &ats,
            &col(|e| &e.actor.token_id),
            &col(|e| &e.actor.role),
            &holders,
            &col(|e| &e.action),
            &col(|e| &e.object),
            &col(|e| &e.change),
            &col(|e| &e.prev),
            &col(|e| &e.hash),
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

/// The `calibration.submitted` events of `stored`, in order, each actor
/// looked up once.
pub async fn stored(
    client: &impl GenericClient,
    stored: &[&crate::store::NewCalibration],
) -> Result<Vec<Event>, StoreError> {
    let mut actors: std::collections::HashMap<&str, Actor> = std::collections::HashMap::new();
    let mut events = Vec::with_capacity(stored.len());
    for n in stored {
        let by = match actors.get(n.submitted_by.as_str()) {
            Some(a) => a.clone(),
            None => {
                let a = submitter(client, &n.submitted_by).await?;
                actors.insert(&n.submitted_by, a.clone());
                a
            }
        };
        events.push(audit::stored(n, by));
    }
    Ok(events)
}

#[async_trait]
impl Audit for PostgresStore {
    async fn record(&self, events: Vec<Event>) -> Result<(), StoreError> {
        op!(self, "audit_record", |client| {
            let tx = client.transaction().await.map_err(map)?;
            append(&tx, events).await?;
            tx.commit().await.map_err(map)?;
            Ok(())
        })
    }

    async fn audit(&self, q: AuditQuery) -> Result<Vec<Entry>, StoreError> {
        op!(self, "audit", |client| {
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

    async fn configure(&self, settings: Map<String, Value>) -> Result<bool, StoreError> {
        op!(self, "audit_configure", |client| {
            let tx = client.transaction().await.map_err(map)?;
            tx.batch_execute("LOCK TABLE audit IN EXCLUSIVE MODE")
                .await
                .map_err(map)?;
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
            append(&tx, vec![event]).await?;
            tx.commit().await.map_err(map)?;
            Ok(true)
        })
    }
}
