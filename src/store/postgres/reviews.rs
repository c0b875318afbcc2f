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
use super::rows::nonconformity;
use super::signatures::SIGNATURE_COLUMNS;
use crate::domain::audit::{Actor, Event};
use crate::domain::events::Effect;
use crate::domain::nonconformity::{Affected, Nonconformity, Replacement, Traced};
use crate::domain::review::{Act, Basis, Refusal, Signature, State, Submitter};
use crate::domain::timestamp::Timestamp;
use crate::store::audit::with_effect;
use crate::store::{
    IssuedCertificate, MadeWith, NewCalibration, Render, Reviews, Signed, StoreError,
    chain_end_sql, changes_the_sensor, earlier_submitters_sql, fitted_into_sql,
    latest_approved_id_sql, made_with_sql, sensor_forget, sensor_recompute,
};

/// The holder of the token `token_id` (a submission's `submitted_by`), if
/// it is a stored token that names one.
async fn holder_of(tx: &Transaction<'_>, token_id: &str) -> Result<Option<String>, StoreError> {
    Ok(match Uuid::try_parse(token_id) {
        Ok(token) => tx
            .query_opt("SELECT holder FROM tokens WHERE id = $1", &[&token])
            .await
            .map_err(map)?
            .map(|r| rows::get::<Option<String>>(&r, "holder"))
            .transpose()?
            .flatten(),
        Err(_) => None,
    })
}

/// Records `act` on calibration `id` within the transaction `tx` — after
/// storing `replacement`, the calibration that supersedes it, when there is
/// one; answers with the audit events the caller appends last
/// ([`super::audit`]: after every row lock of the transaction).
async fn sign(
    tx: &Transaction<'_>,
    id: Uuid,
    act: &Act,
    replacement: Option<&Row>,
    render: Option<Render>,
) -> Result<(Signed, Vec<Event>), StoreError> {
    // The standards a replacement names, locked before anything else
    // ([`super::holds`]).
    if let Some(r) = replacement {
        super::holds::lock(tx, r.new_calibration()).await?;
    }
    let locked = tx
        .query_opt(
            "SELECT id FROM calibrations WHERE id = $1 FOR NO KEY UPDATE",
            &[&id],
        )
        .await
        .map_err(map)?;
    if locked.is_none() {
        return Ok((Signed::NotFound, Vec::new()));
    }
    let row = tx
        .query_one(
            concat!(
                "SELECT c.sensor_id, c.submitted_by, c.received_at, c.performed_at, ",
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
    let holder = holder_of(tx, &submitted_by).await?;
    let mut earlier = Vec::new();
    for r in tx
        .query(&earlier_submitters_sql("$1"), &[&id])
        .await
        .map_err(map)?
    {
        let token: String = rows::get(&r, "submitted_by")?;
        let holder = holder_of(tx, &token).await?;
        earlier.push((token, holder));
    }
    let submitter = Submitter {
        token_id: submitted_by,
        holder,
        received_at,
        earlier,
    };
    let seq = u32::try_from(last + 1).map_err(|e| StoreError::corrupt("signatures", e))?;
    let s = match act.check(state, &submitter, seq) {
        Ok(s) => s,
        Err(refusal) => return Ok((Signed::Refused(refusal), Vec::new())),
    };
    // A replacement fitted from the calibration it supersedes would count
    // on one that does not.
    if let Some(r) = replacement.filter(|r| r.new_calibration().fitted_from.contains(&id)) {
        let model = r.new_calibration().id;
        return Ok((Signed::Refused(Refusal::FittedInto { model }), Vec::new()));
    }
    if state.counts(Basis::NotRejected) && !s.state.counts(Basis::NotRejected) {
        let performed_at: time::OffsetDateTime = rows::get(&row, "performed_at")?;
        let sql = fitted_into_sql(&fitted_from("= $3"), ["$1", "$2", "$3"]);
        let found = tx
            .query_opt(&sql, &[&sensor_id, &performed_at, &id])
            .await
            .map_err(map)?;
        if let Some(model) = found {
            let model = rows::get(&model, "id")?;
            return Ok((Signed::Refused(Refusal::FittedInto { model }), Vec::new()));
        }
    }
    let mut held = Vec::new();
    let mut replacement_latest = false;
    if let Some(r) = replacement {
        match write(tx, r, None).await? {
            Written::New(row) => {
                replacement_latest = row.latest_calibration_id == r.new_calibration().id;
            }
            _ => {
                return Err(StoreError::corrupt(
                    "calibrations",
                    "a replacement without a key was not stored",
                ));
            }
        }
        // A correction of a held calibration is held too, under the same
        // nonconformities, while it uses their standards.
        let inherited = if state == State::UnderReview {
            super::holds::holding(tx, id).await?
        } else {
            Vec::new()
        };
        held = super::holds::place(tx, r.new_calibration(), &inherited, replacement_latest).await?;
    }
    // What the sensor's reads serve before the act (after storing the
    // replacement, whose own entry says what storing it did), the sensor's
    // row locked first, in a statement of its own: the recompute's own
    // snapshot, taken after the lock is held, then sees every calibration
    // committed before it (under READ COMMITTED a statement that waited for
    // the lock would count from its older one).
    let touches = Effect::touches_approved(state, s.state);
    let latest_before = latest_of(tx, &sensor_id, true).await?;
    let approved_before = match touches {
        true => Some(latest_approved_of(tx, &sensor_id).await?),
        false => None,
    };
    super::signatures::insert(tx, id, &s).await?;
    // An approval issues the certificate, with the signatures it leaves,
    // unless one was issued already (an approval after a hold); the
    // calibration's row is locked, so revisions follow one another.
    let unissued = match &render {
        Some(_) => super::certificates::latest(tx, id).await? == 0,
        None => false,
    };
    let issued = match render {
        Some(render) if unissued => {
            let signatures = tx
                .query(
                    &format!(
                        "SELECT {SIGNATURE_COLUMNS} FROM signatures WHERE calibration_id = $1 \
                         ORDER BY seq"
                    ),
                    &[&id],
                )
                .await
                .map_err(map)?
                .iter()
                .map(rows::signature)
                .collect::<Result<Vec<_>, _>>()?;
            let c = IssuedCertificate::new(
                id,
                1,
                s.signed_at,
                Actor::from(&act.signer),
                None,
                render(&signatures, s.state),
            );
            super::certificates::insert(tx, &c).await?;
            Some(c)
        }
        _ => None,
    };
    let latest_after = if changes_the_sensor(state, s.state, replacement.is_some()) {
        tx.execute(&sensor_recompute("$1"), &[&sensor_id])
            .await
            .map_err(map)?;
        tx.execute(&sensor_forget("$1"), &[&sensor_id])
            .await
            .map_err(map)?;
        latest_of(tx, &sensor_id, false).await?
    } else {
        latest_before
    };
    let approved = match approved_before {
        Some(before) => Some((before, latest_approved_of(tx, &sensor_id).await?)),
        None => None,
    };
    let effect = Effect::signed(id, state, s.state, (latest_before, latest_after), approved);
    let mut events = match replacement {
        Some(r) => {
            let written = (r.new_calibration(), r.entry(), replacement_latest);
            super::audit::stored(tx, &[written]).await?
        }
        None => Vec::new(),
    };
    events.extend(held);
    let entry = match &issued {
        Some(c) => crate::store::audit::signed_issuing(id, &s, state, c),
        None => crate::store::audit::signed(id, &s, state),
    };
    events.push(with_effect(entry, effect));
    Ok((Signed::Done(s, sensor_id), events))
}

/// Sensor `sensor_id`'s latest calibration as its row holds it (none: it
/// has no row), the row locked (`lock`) or not: what its reads serve
/// without `--require-approval`.
async fn latest_of(
    tx: &Transaction<'_>,
    sensor_id: &str,
    lock: bool,
) -> Result<Option<Uuid>, StoreError> {
    let sql = if lock {
        "SELECT latest_calibration_id FROM sensors WHERE sensor_id = $1 FOR UPDATE"
    } else {
        "SELECT latest_calibration_id FROM sensors WHERE sensor_id = $1"
    };
    let stmt = tx.prepare_cached(sql).await.map_err(map)?;
    match tx.query_opt(&stmt, &[&sensor_id]).await.map_err(map)? {
        Some(row) => Ok(Some(rows::get(&row, "latest_calibration_id")?)),
        None => Ok(None),
    }
}

/// Sensor `sensor_id`'s latest approved calibration: what its reads serve
/// with `--require-approval`.
async fn latest_approved_of(
    tx: &Transaction<'_>,
    sensor_id: &str,
) -> Result<Option<Uuid>, StoreError> {
    let stmt = tx
        .prepare_cached(&latest_approved_id_sql("$1"))
        .await
        .map_err(map)?;
    match tx.query_opt(&stmt, &[&sensor_id]).await.map_err(map)? {
        Some(row) => Ok(Some(rows::get(&row, "id")?)),
        None => Ok(None),
    }
}

/// Inserts the record of a nonconformity.
async fn insert_nonconformity(tx: &Transaction<'_>, nc: &Nonconformity) -> Result<(), StoreError> {
    let by = &nc.recorded_by;
    tx.execute(
        "INSERT INTO nonconformities (id, standard_id, found_at, last_known_good_at, \
         window_from, reason, recorded_at, token_id, role, holder) \
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
        &[
            &nc.id,
            &nc.standard_id,
            &nc.found_at.datetime(),
            &nc.last_known_good_at.map(|t| t.datetime()),
            &nc.window_from.datetime(),
            &nc.reason,
            &nc.recorded_at.datetime(),
            &by.token_id,
            &by.role,
            &by.holder,
        ],
    )
    .await
    .map_err(map)?;
    Ok(())
}

/// Inserts that `calibration` was in `nc`'s window, in state `found`.
async fn insert_concerned(
    tx: &Transaction<'_>,
    nc: &Nonconformity,
    calibration: Uuid,
    found: State,
) -> Result<(), StoreError> {
    tx.execute(
        "INSERT INTO nonconformity_calibrations (nonconformity_id, calibration_id, \
         state_found) VALUES ($1, $2, $3)",
        &[&nc.id, &calibration, &found.as_str()],
    )
    .await
    .map_err(map)?;
    Ok(())
}

/// The condition that `c.result`'s `from_calibrations` names an id
/// `rhs` matches (`= $3`, `IN (…)`).
fn fitted_from(rhs: &str) -> String {
    format!(
        "EXISTS (SELECT 1 FROM json_array_elements_text(c.result::json -> 'from_calibrations') f \
         WHERE f.value::uuid {rhs})"
    )
}

/// The calibrations made with standard `standard_id` within `from..=to`,
/// and the temperature models fitted from them ([`made_with_sql`]).
async fn made_with_in(
    client: &impl GenericClient,
    standard_id: &str,
    from: Timestamp,
    to: Timestamp,
) -> Result<Vec<MadeWith>, StoreError> {
    let sql = made_with_sql(
        "EXISTS (SELECT 1 FROM json_array_elements(c.result::json -> 'standards') s \
         WHERE s.value ->> 'standard_id' = $1)",
        &fitted_from("IN (SELECT id FROM made)"),
        ["$1", "$2", "$3"],
    );
    client
        .query(&sql, &[&standard_id, &from.datetime(), &to.datetime()])
        .await
        .map_err(map)?
        .iter()
        .map(made_with)
        .collect()
}

/// The nonconformity `nc` recorded and each calibration made with its
/// standard in its window that counts held, within `tx`, the standard's row
/// locked first ([`super::holds`]); the audit trail appended last.
async fn hold(
    tx: &Transaction<'_>,
    nc: &Nonconformity,
    act: &Act,
) -> Result<Vec<Affected>, StoreError> {
    tx.execute(
        "SELECT 1 FROM standards WHERE standard_id = $1 FOR UPDATE",
        &[&nc.standard_id],
    )
    .await
    .map_err(map)?;
    let made = made_with_in(tx, &nc.standard_id, nc.window_from, nc.found_at).await?;
    insert_nonconformity(tx, nc).await?;
    let concerned: Vec<(Uuid, State)> = made.iter().map(|m| (m.calibration_id, m.state)).collect();
    let mut events = vec![crate::store::audit::nonconformity(nc, &concerned)];
    let mut out = Vec::with_capacity(made.len());
    for m in made {
        let now = match sign(tx, m.calibration_id, act, None, None).await? {
            (Signed::Done(s, _), signed) => {
                events.extend(signed);
                s.state
            }
            // It no longer counted, or was under review already: left.
            _ => m.state,
        };
        insert_concerned(tx, nc, m.calibration_id, m.state).await?;
        let found = m.state;
        out.push(m.affected(found, now, None));
    }
    super::audit::append(tx, events).await?;
    Ok(out)
}

fn made_with(r: &tokio_postgres::Row) -> Result<MadeWith, StoreError> {
    Ok(MadeWith {
        calibration_id: rows::get(r, "id")?,
        sensor_id: rows::get(r, "sensor_id")?,
        performed_at: Timestamp::from_datetime(rows::get::<time::OffsetDateTime>(
            r,
            "performed_at",
        )?),
        state: rows::state(r)?,
    })
}

fn affected(r: &tokio_postgres::Row) -> Result<Affected, StoreError> {
    let found: String = rows::get(r, "state_found")?;
    made_with(r)?.found_as(&found)
}

impl PostgresStore {
    /// [`Reviews::sign`], with the replacement of a supersession, or the
    /// rendering of the certificate an approval issues.
    async fn record(
        &self,
        id: Uuid,
        act: Act,
        replacement: Option<Row>,
        render: Option<Render>,
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
            act!(this, "sign", |client| {
                let tx = client.transaction().await.map_err(map)?;
                let (out, events) = sign(&tx, id, &act, replacement.as_ref(), render).await?;
                if matches!(out, Signed::Done(..)) {
                    super::audit::append(&tx, events).await?;
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
        self.record(id, act, None, None).await
    }

    async fn approve_issuing(
        &self,
        id: Uuid,
        act: Act,
        render: Render,
    ) -> Result<Signed, StoreError> {
        self.record(id, act, None, Some(render)).await
    }

    async fn supersede(
        &self,
        id: Uuid,
        replacement: NewCalibration,
        act: Act,
    ) -> Result<Signed, StoreError> {
        let row = Row::new(replacement)?;
        self.record(id, act, Some(row), None).await
    }

    async fn made_with(
        &self,
        standard_id: String,
        from: Timestamp,
        to: Timestamp,
    ) -> Result<Vec<MadeWith>, StoreError> {
        op!(self, "made_with", |client| {
            made_with_in(&client, &standard_id, from, to).await
        })
    }

    async fn hold(&self, nc: Nonconformity, act: Act) -> Result<Vec<Affected>, StoreError> {
        // The sensors whose cached entries the holds change, read first;
        // one stored meanwhile is dropped after.
        let before = self
            .made_with(nc.standard_id.clone(), nc.window_from, nc.found_at)
            .await?;
        let mut sensors: Vec<String> = before.iter().map(|m| m.sensor_id.clone()).collect();
        sensors.sort();
        sensors.dedup();
        let this = self.clone();
        let write = async move {
            act!(this, "hold", |client| {
                let tx = client.transaction().await.map_err(map)?;
                let out = hold(&tx, &nc, &act).await?;
                tx.commit().await.map_err(map)?;
                Ok(out)
            })
        };
        let out = self.cache.changing(&sensors, write).await?;
        for a in out.iter().filter(|a| !sensors.contains(&a.sensor_id)) {
            self.cache.sensor_changed(&a.sensor_id);
        }
        Ok(out)
    }

    async fn findings(&self, standard_ids: Vec<String>) -> Result<Vec<Nonconformity>, StoreError> {
        op!(self, "findings", |client| {
            super::holds::findings(&client, &standard_ids).await
        })
    }

    async fn put_nonconformity(&self, t: Traced) -> Result<(), StoreError> {
        act!(self, "put_nonconformity", |client| {
            let tx = client.transaction().await.map_err(map)?;
            insert_nonconformity(&tx, &t.nonconformity).await?;
            for c in &t.calibrations {
                insert_concerned(&tx, &t.nonconformity, c.calibration_id, c.state_found).await?;
            }
            super::audit::append(&tx, vec![crate::store::audit::traced(&t)]).await?;
            tx.commit().await.map_err(map)?;
            Ok(())
        })
    }

    async fn nonconformities(&self, standard_id: String) -> Result<Vec<Traced>, StoreError> {
        op!(self, "nonconformities", |client| {
            let found = client
                .query(
                    "SELECT id, standard_id, found_at, last_known_good_at, window_from, reason, \
                     recorded_at, token_id, role, holder FROM nonconformities \
                     WHERE standard_id = $1 ORDER BY found_at, id",
                    &[&standard_id],
                )
                .await
                .map_err(map)?;
            let mut out = Vec::with_capacity(found.len());
            for row in &found {
                let nc = nonconformity(row)?;
                let calibrations = client
                    .query(
                        concat!(
                            "SELECT c.id, c.sensor_id, c.performed_at, n.state_found, ",
                            crate::state_sql!(),
                            " AS state FROM nonconformity_calibrations n \
                             JOIN calibrations c ON c.id = n.calibration_id \
                             WHERE n.nonconformity_id = $1 ORDER BY c.performed_at, c.id"
                        ),
                        &[&nc.id],
                    )
                    .await
                    .map_err(map)?
                    .iter()
                    .map(affected)
                    .collect::<Result<Vec<_>, _>>()?;
                let mut calibrations = calibrations;
                for a in &mut calibrations {
                    if a.state != State::Superseded {
                        continue;
                    }
                    if let Some(r) = client
                        .query_opt(&chain_end_sql("$1"), &[&a.calibration_id])
                        .await
                        .map_err(map)?
                    {
                        let by = Replacement {
                            calibration_id: rows::get(&r, "id")?,
                            state: rows::state(&r)?,
                        };
                        *a = a.clone().replaced(by);
                    }
                }
                out.push(Traced {
                    nonconformity: nc,
                    calibrations,
                });
            }
            Ok(out)
        })
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
