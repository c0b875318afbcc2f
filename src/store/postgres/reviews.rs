//! Reviews: signed acts on a calibration, checked against its state in the
//! transaction that records them (the calibration's row locked, so two
//! replicas' acts on one calibration apply one after the other), and its
//! sensor's row computed again.

use async_trait::async_trait;
use deadpool_postgres::{GenericClient, Transaction};
use uuid::Uuid;

use super::PostgresStore;
use super::calibrations::{Row, Written, write};
use super::errors::map;
use super::rows;
use crate::domain::review::{Act, Signature, Submitter};
use crate::domain::timestamp::Timestamp;
use crate::store::{NewCalibration, Reviews, Signed, StoreError, sensor_forget, sensor_recompute};

/// The columns of [`rows::signature`].
const SIGNATURE_COLUMNS: &str =
    "seq, action, state, meaning, token_id, role, holder, signed_at, comment, superseded_by";

/// Records `act` on calibration `id` within the transaction `tx` — after
/// storing `replacement`, the calibration that supersedes it, when there is
/// one.
async fn sign(
    tx: &Transaction<'_>,
    id: Uuid,
    act: &Act,
    replacement: Option<&Row>,
) -> Result<Signed, StoreError> {
    let locked = tx
        .query_opt(
            "SELECT id FROM calibrations WHERE id = $1 FOR NO KEY UPDATE",
            &[&id],
        )
        .await
        .map_err(map)?;
    if locked.is_none() {
        return Ok(Signed::NotFound);
    }
    let row = tx
        .query_one(
            concat!(
                "SELECT c.sensor_id, c.submitted_by, c.received_at, ",
                crate::state_sql!(),
                " AS state, (SELECT coalesce(max(s.seq), 0) FROM signatures s \
                 WHERE s.calibration_id = c.id) AS last FROM calibrations c WHERE c.id = $1"
            ),
            &[&id],
        )
        .await
        .map_err(map)?;
    let sensor_id: String = rows::get(&row, "sensor_id")?;
    let submitted_by: String = rows::get(&row, "submitted_by")?;
    let received_at =
        Timestamp::from_datetime(rows::get::<time::OffsetDateTime>(&row, "received_at")?);
    let state = rows::state(&row)?;
    let last: i32 = rows::get(&row, "last")?;
    let holder = match Uuid::try_parse(&submitted_by) {
        Ok(token) => tx
            .query_opt("SELECT holder FROM tokens WHERE id = $1", &[&token])
            .await
            .map_err(map)?
            .map(|r| rows::get::<Option<String>>(&r, "holder"))
            .transpose()?
            .flatten(),
        Err(_) => None,
    };
    let submitter = Submitter {
        token_id: submitted_by,
        holder,
        received_at,
    };
    let seq = u32::try_from(last + 1).map_err(|e| StoreError::corrupt("signatures", e))?;
    let s = match act.check(state, &submitter, seq) {
        Ok(s) => s,
        Err(refusal) => return Ok(Signed::Refused(refusal)),
    };
    if let Some(r) = replacement {
        match write(tx, r, None).await? {
            Written::New(_) => {}
            _ => {
                return Err(StoreError::corrupt(
                    "calibrations",
                    "a replacement without a key was not stored",
                ));
            }
        }
    }
    let seq = i32::try_from(s.seq).map_err(|e| StoreError::corrupt("signatures", e))?;
    tx.execute(
        &format!(
            "INSERT INTO signatures (calibration_id, {SIGNATURE_COLUMNS}) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11)"
        ),
        &[
            &id,
            &seq,
            &s.action.as_str(),
            &s.state.as_str(),
            &s.meaning,
            &s.token_id,
            &s.role.as_str(),
            &s.holder,
            &s.signed_at.datetime(),
            &s.comment,
            &s.superseded_by,
        ],
    )
    .await
    .map_err(map)?;
    // The sensor's row locked first, in a statement of its own: the
    // recompute's own snapshot, taken after the lock is held, then sees
    // every calibration committed before it (under READ COMMITTED a
    // statement that waited for the lock would count from its older one).
    tx.execute(
        "SELECT 1 FROM sensors WHERE sensor_id = $1 FOR UPDATE",
        &[&sensor_id],
    )
    .await
    .map_err(map)?;
    tx.execute(&sensor_recompute("$1"), &[&sensor_id])
        .await
        .map_err(map)?;
    tx.execute(&sensor_forget("$1"), &[&sensor_id])
        .await
        .map_err(map)?;
    // The audit trail last (its lock after every row lock: super::audit).
    let mut events = match replacement {
        Some(r) => super::audit::stored(tx, &[r.new_calibration()]).await?,
        None => Vec::new(),
    };
    events.push(crate::store::audit::signed(id, &s, state));
    super::audit::append(tx, events).await?;
    Ok(Signed::Done(s, sensor_id))
}

impl PostgresStore {
    /// [`Reviews::sign`], with the replacement of a supersession.
    async fn record(
        &self,
        id: Uuid,
        act: Act,
        replacement: Option<Row>,
    ) -> Result<Signed, StoreError> {
        // A calibration's sensor never changes: read it first, to know
        // which cached entry the write concerns.
        let sensor: Result<Option<String>, StoreError> =
            op!(self, "calibration_sensor", |client| {
                client
                    .query_opt("SELECT sensor_id FROM calibrations WHERE id = $1", &[&id])
                    .await
                    .map_err(map)?
                    .map(|r| rows::get(&r, "sensor_id"))
                    .transpose()
            });
        let Some(sensor) = sensor? else {
            return Ok(Signed::NotFound);
        };
        // A replacement may be of another sensor (a wrong sensor id
        // corrected): both entries are held back and dropped.
        let mut sensors = vec![sensor];
        if let Some(r) = &replacement {
            sensors.push(r.sensor_id().to_owned());
        }
        let this = self.clone();
        let write = async move {
            op!(this, "sign", |client| {
                let tx = client.transaction().await.map_err(map)?;
                let out = sign(&tx, id, &act, replacement.as_ref()).await?;
                if matches!(out, Signed::Done(..)) {
                    tx.commit().await.map_err(map)?;
                }
                Ok(out)
            })
        };
        self.cache.changing(&sensors, write).await
    }
}

#[async_trait]
impl Reviews for PostgresStore {
    /// In a transaction of its own, the sensor's cached summary held back
    /// and dropped ([`crate::store::cache::Cache::changing`]); the sensor's
    /// row being written, every other replica drops it too.
    async fn sign(&self, id: Uuid, act: Act) -> Result<Signed, StoreError> {
        self.record(id, act, None).await
    }

    async fn supersede(
        &self,
        id: Uuid,
        replacement: NewCalibration,
        act: Act,
    ) -> Result<Signed, StoreError> {
        let row = Row::new(replacement)?;
        self.record(id, act, Some(row)).await
    }

    async fn signatures(&self, id: Uuid) -> Result<Vec<Signature>, StoreError> {
        op!(self, "signatures", |client| {
            let found = client
                .query(
                    &format!(
                        "SELECT {SIGNATURE_COLUMNS} FROM signatures WHERE calibration_id = $1 \
                         ORDER BY seq"
                    ),
                    &[&id],
                )
                .await
                .map_err(map)?;
            found.iter().map(rows::signature).collect()
        })
    }
}
