//! Reviews: signed acts on a calibration, checked against its state in the
//! transaction that records them, and its sensor's row computed again.

use async_trait::async_trait;
use rusqlite::{Connection, params};
use uuid::Uuid;

use super::SqliteStore;
use super::rows;
use crate::domain::review::{Act, Signature, Submitter};
use crate::domain::timestamp::Timestamp;
use crate::store::{
    NewCalibration, Reviews, Signed, StoreError, Stored, sensor_forget, sensor_recompute,
};

/// The columns of [`rows::signature`].
const SIGNATURE_COLUMNS: &str =
    "seq, action, state, meaning, token_id, role, holder, signed_at, comment, superseded_by";

/// Records `act` on calibration `id` inside the writer's transaction —
/// after storing `replacement`, the calibration that supersedes it, when
/// there is one; the answer, and whether to commit.
fn sign(
    conn: &Connection,
    id: Uuid,
    act: &Act,
    replacement: Option<NewCalibration>,
) -> Result<(Signed, bool), StoreError> {
    let found = rows::first(
        conn,
        concat!(
            "SELECT c.sensor_id, c.submitted_by, c.received_at, ",
            crate::state_sql!(),
            " AS state, (SELECT coalesce(max(s.seq), 0) FROM signatures s \
             WHERE s.calibration_id = c.id) AS last FROM calibrations c WHERE c.id = ?1"
        ),
        [id.to_string()],
        |r| {
            Ok((
                r.get::<_, String>("sensor_id")
                    .map_err(super::errors::map)?,
                r.get::<_, String>("submitted_by")
                    .map_err(super::errors::map)?,
                r.get::<_, String>("received_at")
                    .map_err(super::errors::map)?,
                rows::state(r)?,
                r.get::<_, i64>("last").map_err(super::errors::map)?,
            ))
        },
    )?;
    let Some((sensor_id, submitted_by, received_at, state, last)) = found else {
        return Ok((Signed::NotFound, false));
    };
    let holder = match Uuid::try_parse(&submitted_by) {
        Ok(token) => rows::first(
            conn,
            "SELECT holder FROM tokens WHERE id = ?1",
            [token.to_string()],
            |r| {
                r.get::<_, Option<String>>("holder")
                    .map_err(super::errors::map)
            },
        )?
        .flatten(),
        Err(_) => None,
    };
    let submitter = Submitter {
        token_id: submitted_by,
        holder,
        received_at: Timestamp::parse(&received_at)
            .map_err(|e| StoreError::corrupt("column `received_at`", e))?,
    };
    let seq = u32::try_from(last + 1).map_err(|e| StoreError::corrupt("signatures", e))?;
    let signature = match act.check(state, &submitter, seq) {
        Ok(s) => s,
        Err(refusal) => return Ok((Signed::Refused(refusal), false)),
    };
    if let Some(n) = replacement {
        match super::calibrations::insert(conn, n, None)? {
            (Stored::New, _) => {}
            (Stored::Existing(_), _) => {
                return Err(StoreError::corrupt(
                    "calibrations",
                    "a replacement without a key was not stored",
                ));
            }
        }
    }
    insert(conn, id, &signature)?;
    super::audit::append(conn, crate::store::audit::signed(id, &signature, state))?;
    rows::execute(conn, &sensor_recompute("?1"), [&sensor_id])?;
    rows::execute(conn, &sensor_forget("?1"), [&sensor_id])?;
    Ok((Signed::Done(signature, sensor_id), true))
}

/// Appends a signature.
fn insert(conn: &Connection, id: Uuid, s: &Signature) -> Result<(), StoreError> {
    rows::execute(
        conn,
        &format!(
            "INSERT INTO signatures (calibration_id, {SIGNATURE_COLUMNS}) \
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)"
        ),
        params![
            id.to_string(),
            s.seq,
            s.action.as_str(),
            s.state.as_str(),
            s.meaning,
            s.token_id,
            s.role.as_str(),
            s.holder,
            s.signed_at.to_string(),
            s.comment,
            s.superseded_by.map(|u| u.to_string())
        ],
    )?;
    Ok(())
}

impl SqliteStore {
    /// [`Reviews::sign`], with the replacement of a supersession.
    async fn record(
        &self,
        id: Uuid,
        act: Act,
        replacement: Option<NewCalibration>,
    ) -> Result<Signed, StoreError> {
        self.follow_the_file()?;
        // A calibration's sensor never changes: read it first, to know
        // which cached entry the write concerns.
        let sensor = self
            .run("calibration_sensor", move |conn| {
                rows::first(
                    conn,
                    "SELECT sensor_id FROM calibrations WHERE id = ?1",
                    [id.to_string()],
                    |r| r.get::<_, String>("sensor_id").map_err(super::errors::map),
                )
            })
            .await?;
        let Some(sensor) = sensor else {
            return Ok(Signed::NotFound);
        };
        // A replacement may be of another sensor (a wrong sensor id
        // corrected): both entries are held back and dropped.
        let mut sensors = vec![sensor];
        if let Some(r) = &replacement {
            sensors.push(r.sensor_id.clone());
        }
        let this = self.clone();
        let write = async move {
            this.write("sign", move |conn| sign(conn, id, &act, replacement))
                .await
        };
        self.cache.changing(&sensors, write).await
    }
}

#[async_trait]
impl Reviews for SqliteStore {
    /// In the writer's next batch, the sensor's cached summary held back
    /// and dropped ([`crate::store::cache::Cache::changing`]).
    async fn sign(&self, id: Uuid, act: Act) -> Result<Signed, StoreError> {
        self.record(id, act, None).await
    }

    async fn supersede(
        &self,
        id: Uuid,
        replacement: NewCalibration,
        act: Act,
    ) -> Result<Signed, StoreError> {
        replacement.check()?;
        self.record(id, act, Some(replacement)).await
    }

    async fn signatures(&self, id: Uuid) -> Result<Vec<Signature>, StoreError> {
        self.run("signatures", move |conn| {
            rows::all(
                conn,
                &format!(
                    "SELECT {SIGNATURE_COLUMNS} FROM signatures WHERE calibration_id = ?1 \
                     ORDER BY seq"
                ),
                [id.to_string()],
                rows::signature,
            )
        })
        .await
    }
}
