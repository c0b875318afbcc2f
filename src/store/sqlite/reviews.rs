//! Reviews: signed acts on a calibration, checked against its state in the
//! transaction that records them, and its sensor's row computed again.

use async_trait::async_trait;
use rusqlite::{Connection, params};
use uuid::Uuid;

use super::SqliteStore;
use super::rows;
use super::rows::nonconformity;
use super::signatures::{SIGNATURE_COLUMNS, insert};
use crate::domain::audit::Actor;
use crate::domain::events::Effect;
use crate::domain::nonconformity::{Affected, Nonconformity, Replacement, Traced};
use crate::domain::review::{Act, Basis, Refusal, Signature, State, Submitter};
use crate::domain::timestamp::Timestamp;
use crate::store::audit::with_effect;
use crate::store::{
    IssuedCertificate, MadeWith, NewCalibration, Render, Reviews, Signed, StoreError, Stored,
    chain_end_sql, changes_the_sensor, earlier_submitters_sql, fitted_into_sql,
    latest_approved_id_sql, made_with_sql, sensor_forget, sensor_recompute,
};

/// Records `act` on calibration `id` inside the writer's transaction —
/// after storing `replacement`, the calibration that supersedes it, when
/// there is one; the answer, and whether to commit.
fn sign(
    conn: &Connection,
    id: Uuid,
    act: &Act,
    replacement: Option<NewCalibration>,
    render: Option<Render>,
) -> Result<(Signed, bool), StoreError> {
    let found = rows::first(
        conn,
        concat!(
            "SELECT c.sensor_id, c.submitted_by, c.received_at, c.performed_at, ",
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
                r.get::<_, String>("performed_at")
                    .map_err(super::errors::map)?,
                rows::state(r)?,
                r.get::<_, i64>("last").map_err(super::errors::map)?,
            ))
        },
    )?;
    let Some((sensor_id, submitted_by, received_at, performed_at, state, last)) = found else {
        return Ok((Signed::NotFound, false));
    };
    let holder = holder_of(conn, &submitted_by)?;
    let earlier = rows::all(conn, &earlier_submitters_sql("?1"), [id.to_string()], |r| {
        r.get::<_, String>("submitted_by")
            .map_err(super::errors::map)
    })?
    .into_iter()
    .map(|token| {
        let holder = holder_of(conn, &token)?;
        Ok((token, holder))
    })
    .collect::<Result<Vec<_>, StoreError>>()?;
    let submitter = Submitter {
        token_id: submitted_by,
        holder,
        received_at: Timestamp::parse(&received_at)
            .map_err(|e| StoreError::corrupt("column `received_at`", e))?,
        earlier,
    };
    let seq = u32::try_from(last + 1).map_err(|e| StoreError::corrupt("signatures", e))?;
    let signature = match act.check(state, &submitter, seq) {
        Ok(s) => s,
        Err(refusal) => return Ok((Signed::Refused(refusal), false)),
    };
    // A replacement fitted from the calibration it supersedes would count
    // on one that does not.
    if let Some(model) = replacement.as_ref().filter(|n| n.fitted_from.contains(&id)) {
        let model = model.id;
        return Ok((Signed::Refused(Refusal::FittedInto { model }), false));
    }
    if state.counts(Basis::NotRejected) && !signature.state.counts(Basis::NotRejected) {
        let model = rows::first(
            conn,
            &fitted_into_sql(&fitted_from("= ?3"), ["?1", "?2", "?3"]),
            params![sensor_id, performed_at, id.to_string()],
            |r| rows::uuid(r, "id"),
        )?;
        if let Some(model) = model {
            return Ok((Signed::Refused(Refusal::FittedInto { model }), false));
        }
    }
    let recompute = changes_the_sensor(state, signature.state, replacement.is_some());
    if let Some(n) = replacement {
        // A correction of a held calibration is held too, under the same
        // nonconformities, while it uses their standards.
        let inherited = if state == State::UnderReview {
            super::holds::holding(conn, &id.to_string())?
        } else {
            Vec::new()
        };
        let entry = crate::store::audit::submitted(&n);
        match super::calibrations::insert(conn, n, None, &inherited, &entry)? {
            (Stored::New, _) => {}
            (Stored::Existing(_), _) => {
                return Err(StoreError::corrupt(
                    "calibrations",
                    "a replacement without a key was not stored",
                ));
            }
        }
    }
    // What the sensor's reads serve before the act (after storing the
    // replacement, whose own entry says what storing it did).
    let touches = Effect::touches_approved(state, signature.state);
    let latest_before = latest_of(conn, &sensor_id)?;
    let approved_before = touches
        .then(|| latest_approved_of(conn, &sensor_id))
        .transpose()?;
    insert(conn, id, &signature)?;
    // An approval issues the certificate, with the signatures it leaves,
    // unless one was issued already (an approval after a hold).
    let issued = match render {
        Some(render) if super::certificates::latest(conn, &id.to_string())? == 0 => {
            let signatures = rows::all(
                conn,
                &format!(
                    "SELECT {SIGNATURE_COLUMNS} FROM signatures WHERE calibration_id = ?1 \
                     ORDER BY seq"
                ),
                [id.to_string()],
                rows::signature,
            )?;
            let c = IssuedCertificate::new(
                id,
                1,
                signature.signed_at,
                Actor::from(&act.signer),
                None,
                render(&signatures, signature.state),
            );
            super::certificates::insert(conn, &c)?;
            Some(c)
        }
        _ => None,
    };
    let latest_after = if recompute {
        rows::execute(conn, &sensor_recompute("?1"), [&sensor_id])?;
        rows::execute(conn, &sensor_forget("?1"), [&sensor_id])?;
        latest_of(conn, &sensor_id)?
    } else {
        latest_before
    };
    let approved = match approved_before {
        Some(before) => Some((before, latest_approved_of(conn, &sensor_id)?)),
        None => None,
    };
    let effect = Effect::signed(
        id,
        state,
        signature.state,
        (latest_before, latest_after),
        approved,
    );
    let event = match &issued {
        Some(c) => crate::store::audit::signed_issuing(id, &signature, state, c),
        None => crate::store::audit::signed(id, &signature, state),
    };
    super::audit::append(conn, with_effect(event, effect))?;
    Ok((Signed::Done(signature, sensor_id), true))
}

/// Sensor `sensor_id`'s latest calibration as its row holds it (none: it
/// has no row): what its reads serve without `--require-approval`.
fn latest_of(conn: &Connection, sensor_id: &str) -> Result<Option<Uuid>, StoreError> {
    rows::first(
        conn,
        "SELECT latest_calibration_id FROM sensors WHERE sensor_id = ?1",
        [sensor_id],
        |r| rows::uuid(r, "latest_calibration_id"),
    )
}

/// Sensor `sensor_id`'s latest approved calibration: what its reads serve
/// with `--require-approval`.
fn latest_approved_of(conn: &Connection, sensor_id: &str) -> Result<Option<Uuid>, StoreError> {
    rows::first(conn, &latest_approved_id_sql("?1"), [sensor_id], |r| {
        rows::uuid(r, "id")
    })
}

/// The holder of the token `token_id` (a submission's `submitted_by`), if
/// it is a stored token that names one.
fn holder_of(conn: &Connection, token_id: &str) -> Result<Option<String>, StoreError> {
    Ok(match Uuid::try_parse(token_id) {
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
    })
}

/// Inserts the record of a nonconformity.
fn insert_nonconformity(conn: &Connection, nc: &Nonconformity) -> Result<(), StoreError> {
    let by = &nc.recorded_by;
    rows::execute(
        conn,
        "INSERT INTO nonconformities (id, standard_id, found_at, last_known_good_at, \
         window_from, reason, recorded_at, token_id, role, holder) \
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
        params![
            nc.id.to_string(),
            nc.standard_id,
            nc.found_at.to_string(),
            nc.last_known_good_at.map(|t| t.to_string()),
            nc.window_from.to_string(),
            nc.reason,
            nc.recorded_at.to_string(),
            by.token_id,
            by.role,
            by.holder
        ],
    )?;
    Ok(())
}

/// Inserts that `calibration` was in `nc`'s window, in state `found`.
fn insert_concerned(
    conn: &Connection,
    nc: &Nonconformity,
    calibration: Uuid,
    found: State,
) -> Result<(), StoreError> {
    rows::execute(
        conn,
        "INSERT INTO nonconformity_calibrations (nonconformity_id, calibration_id, \
         state_found) VALUES (?1, ?2, ?3)",
        params![nc.id.to_string(), calibration.to_string(), found.as_str()],
    )?;
    Ok(())
}

/// The condition that `c.result`'s `from_calibrations` names an id
/// `rhs` matches (`= ?3`, `IN (…)`).
fn fitted_from(rhs: &str) -> String {
    format!(
        "EXISTS (SELECT 1 FROM json_each(c.result, '$.from_calibrations') f WHERE f.value {rhs})"
    )
}

/// The calibrations made with standard `standard_id` within `from..=to`,
/// and the temperature models fitted from them ([`made_with_sql`]).
fn made_with_in(
    conn: &Connection,
    standard_id: &str,
    from: Timestamp,
    to: Timestamp,
) -> Result<Vec<MadeWith>, StoreError> {
    let sql = made_with_sql(
        "EXISTS (SELECT 1 FROM json_each(c.result, '$.standards') s \
         WHERE json_extract(s.value, '$.standard_id') = ?1)",
        &fitted_from("IN (SELECT id FROM made)"),
        ["?1", "?2", "?3"],
    );
    rows::all(
        conn,
        &sql,
        params![standard_id, from.to_string(), to.to_string()],
        made_with,
    )
}

/// The nonconformity `nc` recorded and each calibration made with its
/// standard in its window that counts held, inside the writer's
/// transaction (which no store of a calibration runs beside).
fn hold(conn: &Connection, nc: &Nonconformity, act: &Act) -> Result<Vec<Affected>, StoreError> {
    let made = made_with_in(conn, &nc.standard_id, nc.window_from, nc.found_at)?;
    insert_nonconformity(conn, nc)?;
    let concerned: Vec<(Uuid, State)> = made.iter().map(|m| (m.calibration_id, m.state)).collect();
    super::audit::append(conn, crate::store::audit::nonconformity(nc, &concerned))?;
    let mut out = Vec::with_capacity(made.len());
    for m in made {
        let now = match sign(conn, m.calibration_id, act, None, None)?.0 {
            Signed::Done(s, _) => s.state,
            // It no longer counted, or was under review already: left.
            _ => m.state,
        };
        insert_concerned(conn, nc, m.calibration_id, m.state)?;
        let found = m.state;
        out.push(m.affected(found, now, None));
    }
    Ok(out)
}

fn made_with(r: &rusqlite::Row<'_>) -> Result<MadeWith, StoreError> {
    let performed: String = r.get("performed_at").map_err(super::errors::map)?;
    Ok(MadeWith {
        calibration_id: rows::uuid(r, "id")?,
        sensor_id: r.get("sensor_id").map_err(super::errors::map)?,
        performed_at: Timestamp::parse(&performed)
            .map_err(|e| StoreError::corrupt("column `performed_at`", e))?,
        state: rows::state(r)?,
    })
}

impl SqliteStore {
    /// [`Reviews::sign`], with the replacement of a supersession, or the
    /// rendering of the certificate an approval issues.
    async fn record(
        &self,
        id: Uuid,
        act: Act,
        replacement: Option<NewCalibration>,
        render: Option<Render>,
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
            this.write("sign", move |conn| {
                sign(conn, id, &act, replacement, render)
            })
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
        replacement.check()?;
        self.record(id, act, Some(replacement), None).await
    }

    async fn made_with(
        &self,
        standard_id: String,
        from: Timestamp,
        to: Timestamp,
    ) -> Result<Vec<MadeWith>, StoreError> {
        self.follow_the_file()?;
        self.run("made_with", move |conn| {
            made_with_in(conn, &standard_id, from, to)
        })
        .await
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
            this.write("hold", move |conn| Ok((hold(conn, &nc, &act)?, true)))
                .await
        };
        let out = self.cache.changing(&sensors, write).await?;
        for a in out.iter().filter(|a| !sensors.contains(&a.sensor_id)) {
            self.cache.sensor_changed(&a.sensor_id);
        }
        Ok(out)
    }

    async fn findings(&self, standard_ids: Vec<String>) -> Result<Vec<Nonconformity>, StoreError> {
        self.follow_the_file()?;
        self.run("findings", move |conn| {
            super::holds::findings(conn, &standard_ids)
        })
        .await
    }

    async fn put_nonconformity(&self, t: Traced) -> Result<(), StoreError> {
        self.follow_the_file()?;
        self.write("put_nonconformity", move |conn| {
            insert_nonconformity(conn, &t.nonconformity)?;
            for c in &t.calibrations {
                insert_concerned(conn, &t.nonconformity, c.calibration_id, c.state_found)?;
            }
            super::audit::append(conn, crate::store::audit::traced(&t))?;
            Ok(((), true))
        })
        .await
    }

    async fn nonconformities(&self, standard_id: String) -> Result<Vec<Traced>, StoreError> {
        self.follow_the_file()?;
        self.run("nonconformities", move |conn| {
            let found = rows::all(
                conn,
                "SELECT id, standard_id, found_at, last_known_good_at, window_from, reason, \
                 recorded_at, token_id, role, holder FROM nonconformities \
                 WHERE standard_id = ?1 ORDER BY found_at, id",
                [&standard_id],
                nonconformity,
            )?;
            found
                .into_iter()
                .map(|nc| {
                    let calibrations = rows::all(
                        conn,
                        concat!(
                            "SELECT c.id, c.sensor_id, c.performed_at, n.state_found, ",
                            crate::state_sql!(),
                            " AS state FROM nonconformity_calibrations n \
                             JOIN calibrations c ON c.id = n.calibration_id \
                             WHERE n.nonconformity_id = ?1 ORDER BY c.performed_at, c.id"
                        ),
                        [nc.id.to_string()],
                        affected,
                    )?
                    .into_iter()
                    .map(|a| replaced(conn, a))
                    .collect::<Result<Vec<_>, _>>()?;
                    Ok(Traced {
                        nonconformity: nc,
                        calibrations,
                    })
                })
                .collect()
        })
        .await
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

/// `a` with the last of its replacements, when it was superseded.
fn replaced(conn: &Connection, a: Affected) -> Result<Affected, StoreError> {
    if a.state != State::Superseded {
        return Ok(a);
    }
    let end = rows::first(
        conn,
        &chain_end_sql("?1"),
        [a.calibration_id.to_string()],
        |r| {
            Ok(Replacement {
                calibration_id: rows::uuid(r, "id")?,
                state: rows::state(r)?,
            })
        },
    )?;
    Ok(match end {
        Some(by) => a.replaced(by),
        None => a,
    })
}

fn affected(r: &rusqlite::Row<'_>) -> Result<Affected, StoreError> {
    let found: String = r.get("state_found").map_err(super::errors::map)?;
    made_with(r)?.found_as(&found)
}
