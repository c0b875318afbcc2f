//! Issued certificates, frozen revision by revision ([`crate::store::issued`]).

use async_trait::async_trait;
use deadpool_postgres::{GenericClient, Transaction};
use uuid::Uuid;

use super::PostgresStore;
use super::errors::map;
use super::rows;
use crate::domain::audit::Actor;
use crate::domain::timestamp::Timestamp;
use crate::store::{Certificates, IssuedCertificate, Revision, StoreError};

const COLUMNS: &str = "calibration_id, revision, issued_at, token_id, role, holder, reason, html, \
     dcc, dcc_missing, html_sha256, dcc_sha256";

fn decode(r: &tokio_postgres::Row) -> Result<IssuedCertificate, StoreError> {
    let revision: i32 = rows::get(r, "revision")?;
    Ok(IssuedCertificate {
        calibration_id: rows::get(r, "calibration_id")?,
        revision: u32::try_from(revision).map_err(|e| StoreError::corrupt("certificates", e))?,
        issued_at: Timestamp::from_datetime(rows::get::<time::OffsetDateTime>(r, "issued_at")?),
        issued_by: Actor {
            token_id: rows::get(r, "token_id")?,
            role: rows::get(r, "role")?,
            holder: rows::get(r, "holder")?,
        },
        reason: rows::get(r, "reason")?,
        html: rows::get(r, "html")?,
        dcc: rows::get(r, "dcc")?,
        dcc_missing: rows::get(r, "dcc_missing")?,
        html_sha256: rows::get(r, "html_sha256")?,
        dcc_sha256: rows::get(r, "dcc_sha256")?,
    })
}

/// The latest revision of calibration `id`'s certificate (0: none).
pub async fn latest(client: &impl GenericClient, id: Uuid) -> Result<u32, StoreError> {
    let row = client
        .query_one(
            "SELECT coalesce(max(revision), 0) AS n FROM certificates WHERE calibration_id = $1",
            &[&id],
        )
        .await
        .map_err(map)?;
    let n: i32 = rows::get(&row, "n")?;
    u32::try_from(n).map_err(|e| StoreError::corrupt("certificates", e))
}

/// Stores revision `c` (its predecessor checked by the caller, under the
/// calibration's row lock).
pub async fn insert(tx: &Transaction<'_>, c: &IssuedCertificate) -> Result<(), StoreError> {
    let revision = i32::try_from(c.revision).map_err(|e| StoreError::Refused(e.to_string()))?;
    tx.execute(
        &format!(
            "INSERT INTO certificates ({COLUMNS}) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12)"
        ),
        &[
            &c.calibration_id,
            &revision,
            &c.issued_at.datetime(),
            &c.issued_by.token_id,
            &c.issued_by.role,
            &c.issued_by.holder,
            &c.reason,
            &c.html,
            &c.dcc,
            &c.dcc_missing,
            &c.html_sha256,
            &c.dcc_sha256,
        ],
    )
    .await
    .map_err(map)?;
    Ok(())
}

#[async_trait]
impl Certificates for PostgresStore {
    async fn certificate(
        &self,
        id: Uuid,
        revision: Option<u32>,
    ) -> Result<Option<IssuedCertificate>, StoreError> {
        let revision = revision.map(i64::from);
        op!(self, "certificate", |client| {
            client
                .query_opt(
                    &format!(
                        "SELECT {COLUMNS} FROM certificates WHERE calibration_id = $1 \
                         AND ($2::int8 IS NULL OR revision = $2) ORDER BY revision DESC LIMIT 1"
                    ),
                    &[&id, &revision],
                )
                .await
                .map_err(map)?
                .as_ref()
                .map(decode)
                .transpose()
        })
    }

    async fn revisions(&self, id: Uuid) -> Result<Vec<Revision>, StoreError> {
        op!(self, "certificate_revisions", |client| {
            client
                .query(
                    &format!(
                        "SELECT {COLUMNS} FROM certificates WHERE calibration_id = $1 \
                         ORDER BY revision"
                    ),
                    &[&id],
                )
                .await
                .map_err(map)?
                .iter()
                .map(|r| decode(r).map(|c| Revision::from(&c)))
                .collect()
        })
    }

    async fn issue_certificate(&self, c: IssuedCertificate) -> Result<bool, StoreError> {
        act!(self, "issue_certificate", |client| {
            let tx = client.transaction().await.map_err(map)?;
            // The calibration's row locked: revisions follow one another.
            tx.execute(
                "SELECT 1 FROM calibrations WHERE id = $1 FOR NO KEY UPDATE",
                &[&c.calibration_id],
            )
            .await
            .map_err(map)?;
            if latest(&tx, c.calibration_id).await? + 1 != c.revision {
                return Ok(false);
            }
            insert(&tx, &c).await?;
            super::audit::append(&tx, vec![crate::store::audit::certificate(&c)]).await?;
            tx.commit().await.map_err(map)?;
            Ok(true)
        })
    }
}
