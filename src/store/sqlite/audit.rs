//! The audit trail: entries appended in the writer's transaction of each
//! act (the single writer keeps them in order), and read by query.

use async_trait::async_trait;
use rusqlite::{Connection, Row, params};
use serde_json::{Map, Value};

use super::SqliteStore;
use super::errors::map;
use super::rows;
use crate::domain::audit::{Actor, Entry, Event};
use crate::domain::timestamp::Timestamp;
use crate::store::{Audit, AuditQuery, StoreError, audit};

const COLUMNS: &str = "seq, at, token_id, role, holder, action, object, change, prev, hash";

fn entry(r: &Row<'_>) -> Result<Entry, StoreError> {
    let at: String = r.get("at").map_err(map)?;
    Ok(Entry {
        seq: r.get("seq").map_err(map)?,
        at: Timestamp::parse(&at).map_err(|e| StoreError::corrupt("audit `at`", e))?,
        actor: Actor {
            token_id: r.get("token_id").map_err(map)?,
            role: r.get("role").map_err(map)?,
            holder: r.get("holder").map_err(map)?,
        },
        action: r.get("action").map_err(map)?,
        object: r.get("object").map_err(map)?,
        change: r.get("change").map_err(map)?,
        prev: r.get("prev").map_err(map)?,
        hash: r.get("hash").map_err(map)?,
    })
}

/// Appends `event` after the last entry, in the caller's transaction.
pub fn append(conn: &Connection, event: Event) -> Result<Entry, StoreError> {
    let last = rows::first(
        conn,
        "SELECT seq, hash FROM audit ORDER BY seq DESC LIMIT 1",
        [],
        |r| {
            Ok((
                r.get::<_, i64>("seq").map_err(map)?,
                r.get::<_, String>("hash").map_err(map)?,
            ))
        },
    )?;
    let e = Entry::chain(last.as_ref().map(|(s, h)| (*s, h.as_str())), event);
    rows::execute(
        conn,
        &format!("INSERT INTO audit ({COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)"),
        params![
            e.seq,
            e.at.to_string(),
            e.actor.token_id,
            e.actor.role,
            e.actor.holder,
            e.action,
            e.object,
            e.change,
            e.prev,
            e.hash
        ],
    )?;
    Ok(e)
}

/// The actor of a submission by `token_id` ([`audit::submitter`]).
pub fn submitter(conn: &Connection, token_id: &str) -> Result<Actor, StoreError> {
    let Ok(id) = uuid::Uuid::try_parse(token_id) else {
        return Ok(audit::submitter(token_id, None));
    };
    let found = rows::first(
        conn,
        "SELECT role, holder FROM tokens WHERE id = ?1",
        [id.to_string()],
        |r| {
            Ok((
                r.get::<_, String>("role").map_err(map)?,
                r.get::<_, Option<String>>("holder").map_err(map)?,
            ))
        },
    )?;
    Ok(audit::submitter(token_id, found))
}

#[async_trait]
impl Audit for SqliteStore {
    async fn record(&self, events: Vec<Event>) -> Result<(), StoreError> {
        self.follow_the_file()?;
        self.write("audit_record", move |conn| {
            for e in events {
                append(conn, e)?;
            }
            Ok(((), true))
        })
        .await
    }

    async fn audit(&self, q: AuditQuery) -> Result<Vec<Entry>, StoreError> {
        self.follow_the_file()?;
        self.run("audit", move |conn| {
            rows::all(
                conn,
                &format!(
                    "SELECT {COLUMNS} FROM audit WHERE seq > :after \
                     AND (:object IS NULL OR object = :object) \
                     AND (:actor IS NULL OR token_id IN (:actor, :token) OR holder = :actor) \
                     AND (:from IS NULL OR at >= :from) AND (:to IS NULL OR at <= :to) \
                     ORDER BY seq LIMIT :limit"
                ),
                rusqlite::named_params! {
                    ":after": q.after,
                    ":object": q.object,
                    ":token": q.actor_token(),
                    ":actor": q.actor,
                    ":from": q.from.map(|t| t.to_string()),
                    ":to": q.to.map(|t| t.to_string()),
                    ":limit": i64::try_from(q.limit).unwrap_or(i64::MAX),
                },
                entry,
            )
        })
        .await
    }

    async fn sealed_after(&self, after: i64, limit: usize) -> Result<Vec<Entry>, StoreError> {
        self.follow_the_file()?;
        self.run("audit_sealed_after", move |conn| {
            rows::all(
                conn,
                &format!("SELECT {COLUMNS} FROM audit WHERE seq > ?1 ORDER BY seq LIMIT ?2"),
                params![after, i64::try_from(limit).unwrap_or(i64::MAX)],
                entry,
            )
        })
        .await
    }

    fn trail_grew(&self) -> Option<tokio::sync::watch::Receiver<u64>> {
        Some(self.writer.committed.subscribe())
    }

    async fn audit_head(&self) -> Result<i64, StoreError> {
        self.follow_the_file()?;
        self.run("audit_head", move |conn| {
            conn.query_row("SELECT coalesce(max(seq), 0) FROM audit", [], |r| r.get(0))
                .map_err(map)
        })
        .await
    }

    async fn configure(&self, settings: Map<String, Value>) -> Result<bool, StoreError> {
        self.follow_the_file()?;
        self.write("audit_configure", move |conn| {
            let event = audit::configured(settings, Timestamp::now());
            let last = rows::first(
                conn,
                "SELECT change FROM audit WHERE action = 'service.configure' \
                 ORDER BY seq DESC LIMIT 1",
                [],
                |r| r.get::<_, String>("change").map_err(map),
            )?;
            if last.as_deref() == Some(event.change.as_str()) {
                return Ok((false, false));
            }
            append(conn, event)?;
            Ok((true, true))
        })
        .await
    }
}
