//! Decoding rows by column name into typed records.

use accelcal_core::{Model, TermMap};
use rusqlite::types::FromSql;
use rusqlite::{Connection, Row};
use uuid::Uuid;

use super::errors::map;
use accelcal_core::decision::Verdict;

use crate::domain::auth::Role;
use crate::domain::status::Status;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::{CalibrationSummary, SensorSummary, StoreError};

/// Where a value is in a row: a column name (which rusqlite looks up among
/// the statement's columns, comparing names, on every call) or a [`Col`].
pub trait Column: Copy + std::fmt::Display {
    fn get<T: FromSql>(self, row: &Row<'_>) -> Result<T, StoreError>;
}

impl Column for &str {
    fn get<T: FromSql>(self, row: &Row<'_>) -> Result<T, StoreError> {
        row.get(self).map_err(map)
    }
}

/// A column by position, named for errors: what the summaries read for
/// every row (by name, the lookups were a tenth of a history page's time).
/// [`col!`] checks at compile time that the name is in the list whose
/// position it takes; `rows::tests` that the lists are the queries' columns.
#[derive(Clone, Copy)]
pub struct Col {
    idx: usize,
    name: &'static str,
}

impl std::fmt::Display for Col {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name)
    }
}

impl Column for Col {
    fn get<T: FromSql>(self, row: &Row<'_>) -> Result<T, StoreError> {
        row.get(self.idx).map_err(map)
    }
}

/// Where `name` is in `names` (a compile error when it is not there).
const fn position(names: &[&str], name: &str) -> usize {
    let mut k = 0;
    while k < names.len() {
        let (a, b) = (names[k].as_bytes(), name.as_bytes());
        if a.len() == b.len() {
            let mut i = 0;
            while i < a.len() && a[i] == b[i] {
                i += 1;
            }
            if i == a.len() {
                return k;
            }
        }
        k += 1;
    }
    panic!("no such column in the list")
}

/// The column `name` of the list `names`, which starts at `base` in the row.
macro_rules! col {
    ($names:expr, $base:expr, $name:literal) => {
        Col {
            idx: $base + const { position(&$names, $name) },
            name: $name,
        }
    };
}

/// A column as text, decoded by `parse` (the row's id names it in errors).
fn decoded<T, E>(
    row: &Row<'_>,
    column: impl Column,
    parse: impl FnOnce(&str) -> Result<T, E>,
) -> Result<T, StoreError>
where
    E: Into<crate::store::BoxError>,
{
    let text: String = column.get(row)?;
    parse(&text).map_err(|e| StoreError::corrupt(format!("column `{column}` ({text:?})"), e))
}

fn timestamp(row: &Row<'_>, column: impl Column) -> Result<Timestamp, StoreError> {
    decoded(row, column, Timestamp::parse)
}

fn optional_timestamp(row: &Row<'_>, column: impl Column) -> Result<Option<Timestamp>, StoreError> {
    let text: Option<String> = column.get(row)?;
    text.map(|t| {
        Timestamp::parse(&t).map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
    })
    .transpose()
}

/// A UUID column.
pub fn uuid(row: &Row<'_>, column: impl Column) -> Result<Uuid, StoreError> {
    decoded(row, column, Uuid::try_parse)
}

fn json<T: serde::de::DeserializeOwned>(
    row: &Row<'_>,
    column: impl Column,
) -> Result<T, StoreError> {
    decoded(row, column, |text: &str| serde_json::from_str::<T>(text))
}

fn optional_json<T: serde::de::DeserializeOwned>(
    row: &Row<'_>,
    column: impl Column,
) -> Result<Option<T>, StoreError> {
    let text: Option<String> = column.get(row)?;
    text.map(|t| {
        serde_json::from_str::<T>(&t)
            .map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
    })
    .transpose()
}

fn count(row: &Row<'_>, column: impl Column) -> Result<u64, StoreError> {
    let n: i64 = column.get(row)?;
    u64::try_from(n).map_err(|e| StoreError::corrupt(format!("column `{column}`"), e))
}

/// The columns of [`summary`], from `calibrations c`: [`SUMMARY`].
pub const SUMMARY_COLUMNS: &str = "c.id, c.sensor_id, c.station_id, c.performed_at, c.received_at, \
     c.unit, c.model, c.runs, c.coefficients, c.std_errors, c.sensor_type, c.verdict, c.due_at, \
     c.expanded";

/// The names of [`SUMMARY_COLUMNS`], in order.
const SUMMARY: [&str; 14] = [
    "id",
    "sensor_id",
    "station_id",
    "performed_at",
    "received_at",
    "unit",
    "model",
    "runs",
    "coefficients",
    "std_errors",
    "sensor_type",
    "verdict",
    "due_at",
    "expanded",
];

fn verdict(row: &Row<'_>, column: impl Column) -> Result<Option<Verdict>, StoreError> {
    let text: Option<String> = column.get(row)?;
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

/// A calibration summary from a row holding [`SUMMARY_COLUMNS`] first.
pub fn summary(row: &Row<'_>) -> Result<CalibrationSummary, StoreError> {
    summary_at(row, 0)
}

/// A calibration summary from a row holding [`SUMMARY_COLUMNS`] from its
/// `base`-th column on.
fn summary_at(row: &Row<'_>, base: usize) -> Result<CalibrationSummary, StoreError> {
    Ok(CalibrationSummary {
        id: uuid(row, col!(SUMMARY, base, "id"))?,
        sensor_id: col!(SUMMARY, base, "sensor_id").get(row)?,
        station_id: col!(SUMMARY, base, "station_id").get(row)?,
        performed_at: timestamp(row, col!(SUMMARY, base, "performed_at"))?,
        received_at: timestamp(row, col!(SUMMARY, base, "received_at"))?,
        unit: col!(SUMMARY, base, "unit").get(row)?,
        model: json::<Model>(row, col!(SUMMARY, base, "model"))?,
        runs: count(row, col!(SUMMARY, base, "runs"))? as usize,
        coefficients: json::<TermMap<f64>>(row, col!(SUMMARY, base, "coefficients"))?,
        std_errors: json::<TermMap<f64>>(row, col!(SUMMARY, base, "std_errors"))?,
        sensor_type: col!(SUMMARY, base, "sensor_type").get(row)?,
        verdict: verdict(row, col!(SUMMARY, base, "verdict"))?,
        due_at: optional_timestamp(row, col!(SUMMARY, base, "due_at"))?,
        expanded: optional_json::<TermMap<f64>>(row, col!(SUMMARY, base, "expanded"))?,
    })
}

/// The columns of [`record`]: everything stored for a calibration.
pub const RECORD_COLUMNS: &str = "c.id, c.sensor_id, c.station_id, c.performed_at, c.received_at, \
     c.unit, c.model, c.runs, c.coefficients, c.std_errors, c.sensor_type, c.verdict, c.due_at, \
     c.expanded, c.result, c.submission, c.content_type, c.submitted_by";

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
    })
}

/// A sensor's status (domain rule [`Status::of`]) in SQL, at `?now` and
/// `?soon` (now plus 30 days), named parameters of the query.
pub const STATUS: &str = "CASE WHEN s.latest_verdict = 'fail' THEN 'failed' \
     WHEN s.latest_due_at IS NULL THEN 'unknown' \
     WHEN s.latest_due_at < :now THEN 'overdue' \
     WHEN s.latest_due_at < :soon THEN 'due_soon' ELSE 'ok' END";

/// The names of the sensor's columns in [`sensor_query`], before its latest
/// calibration's [`SUMMARY_COLUMNS`].
const SENSOR: [&str; 7] = [
    "calibration_count",
    "first_performed_at",
    "latest_performed_at",
    "assigned_type",
    "latest_verdict",
    "latest_due_at",
    "status",
];

/// The sensor columns ([`SENSOR`]) beside [`SUMMARY_COLUMNS`] of its latest
/// calibration (the calibration's own type column is the one named
/// `sensor_type`; the sensor's assigned type is `assigned_type`).
pub fn sensor_query(filter: &str) -> String {
    format!(
        "SELECT s.calibration_count, s.first_performed_at, s.latest_performed_at, \
         s.sensor_type AS assigned_type, s.latest_verdict, s.latest_due_at, {STATUS} AS status, \
         {SUMMARY_COLUMNS} \
         FROM sensors s JOIN calibrations c ON c.id = s.latest_calibration_id {filter}"
    )
}

/// A sensor summary from a row of [`sensor_query`].
pub fn sensor(row: &Row<'_>) -> Result<SensorSummary, StoreError> {
    let latest = summary_at(row, SENSOR.len())?;
    Ok(SensorSummary {
        sensor_id: latest.sensor_id.clone(),
        calibration_count: count(row, col!(SENSOR, 0, "calibration_count"))?,
        first_performed_at: timestamp(row, col!(SENSOR, 0, "first_performed_at"))?,
        latest_performed_at: timestamp(row, col!(SENSOR, 0, "latest_performed_at"))?,
        sensor_type: col!(SENSOR, 0, "assigned_type").get(row)?,
        latest_verdict: verdict(row, col!(SENSOR, 0, "latest_verdict"))?,
        due_at: optional_timestamp(row, col!(SENSOR, 0, "latest_due_at"))?,
        status: decoded(row, col!(SENSOR, 0, "status"), |s| {
            Status::parse(s).ok_or("not a status")
        })?,
        latest,
    })
}

/// The columns of [`token`].
pub const TOKEN_COLUMNS: &str = "id, secret_hash, role, station_id, label, created_at, revoked_at";

/// A token from a row holding [`TOKEN_COLUMNS`].
pub fn token(row: &Row<'_>) -> Result<TokenRecord, StoreError> {
    Ok(TokenRecord {
        id: uuid(row, "id")?,
        secret_hash: row.get("secret_hash").map_err(map)?,
        role: decoded(row, "role", |r| Role::parse(r).ok_or("not a role"))?,
        station_id: row.get("station_id").map_err(map)?,
        label: row.get("label").map_err(map)?,
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

    /// Summaries and sensors are read by position: the lists they are read
    /// with are the queries' columns, in order.
    #[test]
    fn the_positional_lists_are_the_queries_columns() {
        let summary = columns(&format!("SELECT {SUMMARY_COLUMNS} FROM calibrations c"));
        assert_eq!(summary, SUMMARY);
        let sensor = columns(&sensor_query(""));
        let expected: Vec<&str> = SENSOR.iter().chain(SUMMARY.iter()).copied().collect();
        assert_eq!(sensor, expected);
        let record = columns(&format!("SELECT {RECORD_COLUMNS} FROM calibrations c"));
        assert_eq!(record[..SUMMARY.len()], SUMMARY);
    }

    #[test]
    fn a_column_is_found_by_name_at_compile_time() {
        let c = col!(SENSOR, 0, "status");
        assert_eq!((c.idx, c.to_string()), (6, "status".to_owned()));
        let c = col!(SUMMARY, SENSOR.len(), "sensor_id");
        assert_eq!((c.idx, c.name), (8, "sensor_id"));
        assert_eq!(position(&["a", "ab", "b"], "b"), 2);
    }
}
