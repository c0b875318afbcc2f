//! Issued certificates, frozen revision by revision ([`crate::store::issued`]).

use async_trait::async_trait;
use rusqlite::{Connection, params};
use uuid::Uuid;

use super::SqliteStore;
use super::errors::map;
use super::{audit, rows};
use crate::domain::audit::Actor;
use crate::store::{Certificates, IssuedCertificate, Revision, StoreError};

const COLUMNS: &str = "calibration_id, revision, issued_at, token_id, role, holder, reason, html, \
     dcc, dcc_missing, html_sha256, dcc_sha256";

fn decode(r: &rusqlite::Row<'_>) -> Result<IssuedCertificate, StoreError> {
    let revision: i64 = r.get("revision").map_err(map)?;
    Ok(IssuedCertificate {
        calibration_id: rows::uuid(r, "calibration_id")?,
        revision: u32::try_from(revision).map_err(|e| StoreError::corrupt("certificates", e))?,
        issued_at: rows::timestamp(r, "issued_at")?,
        issued_by: Actor {
            token_id: r.get("token_id").map_err(map)?,
            role: r.get("role").map_err(map)?,
            holder: r.get("holder").map_err(map)?,
        },
        reason: r.get("reason").map_err(map)?,
        html: r.get("html").map_err(map)?,
        dcc: r.get("dcc").map_err(map)?,
        dcc_missing: r.get("dcc_missing").map_err(map)?,
        html_sha256: r.get("html_sha256").map_err(map)?,
        dcc_sha256: r.get("dcc_sha256").map_err(map)?,
    })
}

/// The latest revision of calibration `id`'s certificate (0: none).
pub(super) fn latest(conn: &Connection, id: &str) -> Result<u32, StoreError> {
    let n: i64 = rows::first(
        conn,
        "SELECT coalesce(max(revision), 0) AS n FROM certificates WHERE calibration_id = ?1",
        [id],
        |r| r.get::<_, i64>("n").map_err(map),
    )?
    .unwrap_or(0);
    u32::try_from(n).map_err(|e| StoreError::corrupt("certificates", e))
}

/// Stores revision `c` (its predecessor checked by the caller).
pub(super) fn insert(conn: &Connection, c: &IssuedCertificate) -> Result<(), StoreError> {
    rows::execute(
        conn,
        &format!(
            "INSERT INTO certificates ({COLUMNS}) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)"
        ),
        params![
            c.calibration_id.to_string(),
            c.revision,
            c.issued_at.to_string(),
            c.issued_by.token_id,
            c.issued_by.role,
            c.issued_by.holder,
            c.reason,
            c.html,
            c.dcc,
            c.dcc_missing,
            c.html_sha256,
            c.dcc_sha256
        ],
    )?;
    Ok(())
}

#[async_trait]
impl Certificates for SqliteStore {
    async fn certificate(
        &self,
        id: Uuid,
        revision: Option<u32>,
    ) -> Result<Option<IssuedCertificate>, StoreError> {
        self.follow_the_file()?;
        self.run("certificate", move |conn| {
            rows::first(
                conn,
                &format!(
                    "SELECT {COLUMNS} FROM certificates WHERE calibration_id = ?1 \
                     AND (?2 IS NULL OR revision = ?2) ORDER BY revision DESC LIMIT 1"
                ),
                params![id.to_string(), revision],
                decode,
            )
        })
        .await
    }

    async fn revisions(&self, id: Uuid) -> Result<Vec<Revision>, StoreError> {
        self.follow_the_file()?;
        self.run("certificate_revisions", move |conn| {
            rows::all(
                conn,
                &format!(
                    "SELECT {COLUMNS} FROM certificates WHERE calibration_id = ?1 \
                     ORDER BY revision"
                ),
                [id.to_string()],
                |r| decode(r).map(|c| Revision::from(&c)),
            )
        })
        .await
    }

    async fn issue_certificate(&self, c: IssuedCertificate) -> Result<bool, StoreError> {
        self.follow_the_file()?;
        self.write("issue_certificate", move |conn| {
            if latest(conn, &c.calibration_id.to_string())? + 1 != c.revision {
                return Ok((false, false));
            }
            insert(conn, &c)?;
            audit::append(conn, crate::store::audit::certificate(&c))?;
            Ok((true, true))
        })
        .await
    }
}
