//! Decoding rows by column name into typed records.

use accelcal_core::{Model, TermMap};
use rusqlite::types::FromSql;
use rusqlite::{Connection, Row};
use uuid::Uuid;

use super::errors::map;
use accelcal_core::decision::Verdict;

use crate::domain::audit::Actor;
use crate::domain::auth::Role;
use crate::domain::nonconformity::Nonconformity;
use crate::domain::review::{Action, Signature, State};
use crate::domain::status::Status;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::{CalibrationSummary, SensorRow, SensorSummary, StoreError};

/// A column's value, by name (the name is the column's in errors).
fn get<T: FromSql>(row: &Row<'_>, column: &str) -> Result<T, StoreError> {
    row.get(column).map_err(map)
}

/// A column as text, decoded by `parse` (the row's id names it in errors).
fn decoded<T, E>(
    row: &Row<'_>,
    column: &str,
    parse: impl FnOnce(&str) -> Result<T, E>,
) -> Result<T, StoreError>
where
    E: Into<crate::store::BoxError>,
{
    let text: String = get(row, column)?;
    parse(&text).map_err(|e| StoreError::corrupt(format!("column `{column}` ({text:?})"), e))
}

pub fn timestamp(row: &Row<'_>, column: &str) -> Result<Timestamp, StoreError> {
    decoded(row, column, Timestamp::parse)
}

pub fn optional_timestamp(row: &Row<'_>, column: &str) -> Result<Option<Timestamp>, StoreError> {
    let text: Option<String> = get(row, column)?;
    text.map(|t| {
        Timestamp::parse(&t).map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
    })
    .transpose()
}

/// A UUID column.
pub fn uuid(row: &Row<'_>, column: &str) -> Result<Uuid, StoreError> {
    decoded(row, column, Uuid::try_parse)
}

fn json<T: serde::de::DeserializeOwned>(row: &Row<'_>, column: &str) -> Result<T, StoreError> {
    decoded(row, column, |text: &str| serde_json::from_str::<T>(text))
}

fn optional_json<T: serde::de::DeserializeOwned>(
    row: &Row<'_>,
    column: &str,
) -> Result<Option<T>, StoreError> {
    let text: Option<String> = get(row, column)?;
    text.map(|t| {
        serde_json::from_str::<T>(&t)
            .map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
    })
    .transpose()
}

fn count(row: &Row<'_>, column: &str) -> Result<u64, StoreError> {
    let n: i64 = get(row, column)?;
    u64::try_from(n).map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
}

/// The columns of [`summary`], from `calibrations c`.
pub const SUMMARY_COLUMNS: &str = concat!(
    "c.id, c.sensor_id, c.station_id, c.performed_at, c.received_at, \
     c.unit, c.model, c.runs, c.coefficients, c.std_errors, c.sensor_type, c.verdict, c.due_at, \
     c.expanded, c.triad, c.thermal, ",
    crate::state_sql!(),
    " AS state"
);

fn verdict(row: &Row<'_>, column: &str) -> Result<Option<Verdict>, StoreError> {
    let text: Option<String> = get(row, column)?;
    text.map(|v| {
        [Verdict::Pass, Verdict::Conditional, Verdict::Fail]
            .into_iter()
            .find(|x| x.as_str() == v)
            .ok_or_else(|| {
                StoreError::corrupt(format!("column `{column}` ({v:?})"), "not a verdict")
            })
    })
    .transpose()
}

/// A calibration summary from a row holding [`SUMMARY_COLUMNS`].
pub fn summary(row: &Row<'_>) -> Result<CalibrationSummary, StoreError> {
    let (thermal, thermal_triad) = crate::domain::thermal::AnyModel::split(optional_json::<
        crate::domain::thermal::AnyModel,
    >(row, "thermal")?);
    Ok(CalibrationSummary {
        id: uuid(row, "id")?,
        sensor_id: get(row, "sensor_id")?,
        station_id: get(row, "station_id")?,
        performed_at: timestamp(row, "performed_at")?,
        received_at: timestamp(row, "received_at")?,
        unit: get(row, "unit")?,
        model: json::<Model>(row, "model")?,
        runs: count(row, "runs")? as usize,
        coefficients: json::<TermMap<f64>>(row, "coefficients")?,
        std_errors: json::<TermMap<f64>>(row, "std_errors")?,
        sensor_type: get(row, "sensor_type")?,
        verdict: verdict(row, "verdict")?,
        due_at: optional_timestamp(row, "due_at")?,
        expanded: optional_json::<TermMap<f64>>(row, "expanded")?,
        triad: optional_json::<crate::store::TriadElements>(row, "triad")?.map(Box::new),
        thermal: thermal.map(Box::new),
        thermal_triad: thermal_triad.map(Box::new),
        state: state(row)?,
    })
}

/// The columns of [`record`]: everything stored for a calibration.
pub const RECORD_COLUMNS: &str = concat!(
    "c.id, c.sensor_id, c.station_id, c.performed_at, c.received_at, \
     c.unit, c.model, c.runs, c.coefficients, c.std_errors, c.sensor_type, c.verdict, c.due_at, \
     c.expanded, c.triad, c.thermal, c.result, c.submission, c.content_type, c.submitted_by, ",
    crate::state_sql!(),
    " AS state"
);

/// A whole calibration from a row holding [`RECORD_COLUMNS`].
pub fn record(row: &Row<'_>) -> Result<crate::store::NewCalibration, StoreError> {
    let s = summary(row)?;
    let result: String = row.get("result").map_err(map)?;
    let submission: Vec<u8> = row.get("submission").map_err(map)?;
    Ok(crate::store::NewCalibration {
        id: s.id,
        sensor_id: s.sensor_id,
        station_id: s.station_id,
        performed_at: s.performed_at,
        received_at: s.received_at,
        unit: s.unit,
        model: s.model,
        runs: s.runs,
        coefficients: s.coefficients,
        std_errors: s.std_errors,
        result: bytes::Bytes::from(result),
        submission: bytes::Bytes::from(submission),
        content_type: row.get("content_type").map_err(map)?,
        submitted_by: row.get("submitted_by").map_err(map)?,
        sensor_type: s.sensor_type,
        assigns_type: false,
        verdict: s.verdict,
        due_at: s.due_at,
        expanded: s.expanded,
        triad: s.triad,
        thermal: s.thermal,
        thermal_triad: s.thermal_triad,
        standards: Vec::new(),
        fitted_from: Vec::new(),
    })
}

/// The sensor's columns beside [`SUMMARY_COLUMNS`] of its latest
/// calibration (the calibration's own type column is the one named
/// `sensor_type`; the sensor's assigned type is `assigned_type`).
pub fn sensor_query(filter: &str) -> String {
    format!(
        "SELECT s.calibration_count, s.first_performed_at, s.latest_performed_at, \
         s.sensor_type AS assigned_type, s.latest_verdict, s.latest_due_at, {} AS status, \
         {SUMMARY_COLUMNS} \
         FROM sensors s JOIN calibrations c ON c.id = s.latest_calibration_id {filter}",
        Status::sql(":now", ":soon")
    )
}

/// A sensor summary from a row of [`sensor_query`].
pub fn sensor(row: &Row<'_>) -> Result<SensorSummary, StoreError> {
    let latest = summary(row)?;
    Ok(SensorSummary {
        sensor_id: latest.sensor_id.clone(),
        calibration_count: count(row, "calibration_count")?,
        first_performed_at: timestamp(row, "first_performed_at")?,
        latest_performed_at: timestamp(row, "latest_performed_at")?,
        sensor_type: get(row, "assigned_type")?,
        latest_verdict: verdict(row, "latest_verdict")?,
        due_at: optional_timestamp(row, "latest_due_at")?,
        status: decoded(row, "status", |s| Status::parse(s).ok_or("not a status"))?,
        latest,
    })
}

/// A sensor's row as the sensors' upsert answers it
/// ([`crate::store::SENSOR_ROW`]).
pub fn sensor_row(row: &Row<'_>) -> Result<SensorRow, StoreError> {
    Ok(SensorRow {
        sensor_id: get(row, "sensor_id")?,
        calibration_count: count(row, "calibration_count")?,
        first_performed_at: timestamp(row, "first_performed_at")?,
        latest_performed_at: timestamp(row, "latest_performed_at")?,
        latest_calibration_id: uuid(row, "latest_calibration_id")?,
        sensor_type: get(row, "sensor_type")?,
        latest_verdict: verdict(row, "latest_verdict")?,
        due_at: optional_timestamp(row, "latest_due_at")?,
    })
}

/// The columns of [`token`].
pub const TOKEN_COLUMNS: &str =
    "id, secret_hash, role, station_id, label, created_at, revoked_at, holder";

/// A token from a row holding [`TOKEN_COLUMNS`].
pub fn token(row: &Row<'_>) -> Result<TokenRecord, StoreError> {
    Ok(TokenRecord {
        id: uuid(row, "id")?,
        secret_hash: row.get("secret_hash").map_err(map)?,
        role: decoded(row, "role", |r| Role::parse(r).ok_or("not a role"))?,
        station_id: row.get("station_id").map_err(map)?,
        label: row.get("label").map_err(map)?,
        holder: row.get("holder").map_err(map)?,
        created_at: timestamp(row, "created_at")?,
        revoked_at: optional_timestamp(row, "revoked_at")?,
    })
}

/// Every row of a query (a cached statement), decoded by `decode`.
pub fn all<T>(
    conn: &Connection,
    sql: &str,
    params: impl rusqlite::Params,
    mut decode: impl FnMut(&Row<'_>) -> Result<T, StoreError>,
) -> Result<Vec<T>, StoreError> {
    let mut stmt = conn.prepare_cached(sql).map_err(map)?;
    let mut rows = stmt.query(params).map_err(map)?;
    let mut out = Vec::new();
    while let Some(row) = rows.next().map_err(map)? {
        out.push(decode(row)?);
    }
    Ok(out)
}

/// Runs a statement (a cached one: the writer runs the same few statements
/// for every calibration, and preparing one costs more than running it);
/// how many rows it changed.
pub fn execute(
    conn: &Connection,
    sql: &str,
    params: impl rusqlite::Params,
) -> Result<usize, StoreError> {
    conn.prepare_cached(sql)
        .and_then(|mut stmt| stmt.execute(params))
        .map_err(map)
}

/// The first row of a query, if any.
pub fn first<T>(
    conn: &Connection,
    sql: &str,
    params: impl rusqlite::Params,
    decode: impl Fn(&Row<'_>) -> Result<T, StoreError>,
) -> Result<Option<T>, StoreError> {
    let mut stmt = conn.prepare_cached(sql).map_err(map)?;
    let mut rows = stmt.query(params).map_err(map)?;
    rows.next().map_err(map)?.map(decode).transpose()
}

/// A calibration's state, from the column `state`.
pub fn state(row: &Row<'_>) -> Result<State, StoreError> {
    decoded(row, "state", |s| State::parse(s).ok_or("not a state"))
}

/// A signature, from a row of `signatures`.
pub fn signature(row: &Row<'_>) -> Result<Signature, StoreError> {
    Ok(Signature {
        seq: u32::try_from(get::<i64>(row, "seq")?)
            .map_err(|e| StoreError::corrupt("column `seq`", e))?,
        action: decoded(row, "action", |a| Action::parse(a).ok_or("not an action"))?,
        state: state(row)?,
        meaning: get(row, "meaning")?,
        token_id: get(row, "token_id")?,
        role: decoded(row, "role", |r| Role::parse(r).ok_or("not a role"))?,
        holder: get(row, "holder")?,
        signed_at: timestamp(row, "signed_at")?,
        comment: get(row, "comment")?,
        superseded_by: get::<Option<String>>(row, "superseded_by")?
            .map(|t| Uuid::try_parse(&t))
            .transpose()
            .map_err(|e| StoreError::corrupt("column `superseded_by`", e))?,
    })
}

/// A nonconformity of a standard, from its row.
pub fn nonconformity(r: &rusqlite::Row<'_>) -> Result<Nonconformity, StoreError> {
    use super::errors::map;
    let at = |column: &str| -> Result<Timestamp, StoreError> {
        let text: String = r.get(column).map_err(map)?;
        Timestamp::parse(&text).map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
    };
    let good: Option<String> = r.get("last_known_good_at").map_err(map)?;
    Ok(Nonconformity {
        id: uuid(r, "id")?,
        standard_id: r.get("standard_id").map_err(map)?,
        found_at: at("found_at")?,
        last_known_good_at: good
            .map(|t| {
                Timestamp::parse(&t)
                    .map_err(|e| StoreError::corrupt("column `last_known_good_at`", e))
            })
            .transpose()?,
        window_from: at("window_from")?,
        reason: r.get("reason").map_err(map)?,
        recorded_at: at("recorded_at")?,
        recorded_by: Actor {
            token_id: r.get("token_id").map_err(map)?,
            role: r.get("role").map_err(map)?,
            holder: r.get("holder").map_err(map)?,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::super::pool::Pool;
    use super::*;

    /// The column names of `sql`, as SQLite prepares it on the real schema.
    fn columns(sql: &str) -> Vec<String> {
        let dir = tempfile::tempdir().unwrap();
        let pool = Pool::create(dir.path().join("columns.db")).unwrap();
        let p = pool.checkout().unwrap();
        let stmt = p.conn.prepare(sql).unwrap();
        stmt.column_names().map(str::to_owned).collect()
    }

    /// Rows are read by column name, so no query may name a column twice
    /// (the sensor's own type is `assigned_type` beside its latest
    /// calibration's `sensor_type`).
    #[test]
    fn every_column_is_named_once() {
        for sql in [
            sensor_query(""),
            format!("SELECT {RECORD_COLUMNS} FROM calibrations c"),
        ] {
            let names = columns(&sql);
            let unique: std::collections::BTreeSet<_> = names.iter().collect();
            assert_eq!(unique.len(), names.len(), "{names:?}");
        }
        let sensor = columns(&sensor_query(""));
        for name in ["assigned_type", "sensor_type", "status", "latest_due_at"] {
            assert!(sensor.iter().any(|c| c == name), "{name} in {sensor:?}");
        }
    }
}
