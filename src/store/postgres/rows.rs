//! Decoding rows by column name into typed records.

use accelcal_core::decision::Verdict;
use accelcal_core::{Model, TermMap};
use tokio_postgres::Row;
use tokio_postgres::types::FromSql;

use super::errors::decode;
use crate::domain::audit::{Actor, Event};
use crate::domain::auth::Role;
use crate::domain::nonconformity::Nonconformity;
use crate::domain::review::{Action, Signature, State};
use crate::domain::status::Status;
use crate::domain::timestamp::Timestamp;
use crate::domain::tokens::TokenRecord;
use crate::store::{CalibrationSummary, NewCalibration, SensorRow, SensorSummary, StoreError};

/// A column of a row.
pub fn get<'a, T: FromSql<'a>>(row: &'a Row, column: &str) -> Result<T, StoreError> {
    row.try_get(column).map_err(|e| decode(column, e))
}

pub fn timestamp(row: &Row, column: &str) -> Result<Timestamp, StoreError> {
    get::<time::OffsetDateTime>(row, column).map(Timestamp::from_datetime)
}

pub fn optional_timestamp(row: &Row, column: &str) -> Result<Option<Timestamp>, StoreError> {
    Ok(get::<Option<time::OffsetDateTime>>(row, column)?.map(Timestamp::from_datetime))
}

/// A JSON column selected as text (`column::text AS column`).
fn json<T: serde::de::DeserializeOwned>(row: &Row, column: &str) -> Result<T, StoreError> {
    let text: &str = get(row, column)?;
    serde_json::from_str(text).map_err(|e| decode(column, e))
}

fn optional_json<T: serde::de::DeserializeOwned>(
    row: &Row,
    column: &str,
) -> Result<Option<T>, StoreError> {
    get::<Option<&str>>(row, column)?
        .map(|t| serde_json::from_str(t).map_err(|e| decode(column, e)))
        .transpose()
}

fn count(row: &Row, column: &str) -> Result<u64, StoreError> {
    let n: i64 = get(row, column)?;
    u64::try_from(n).map_err(|e| decode(column, e))
}

fn verdict(row: &Row, column: &str) -> Result<Option<Verdict>, StoreError> {
    get::<Option<&str>>(row, column)?
        .map(|v| {
            [Verdict::Pass, Verdict::Conditional, Verdict::Fail]
                .into_iter()
                .find(|x| x.as_str() == v)
                .ok_or_else(|| decode(column, "not a verdict"))
        })
        .transpose()
}

/// The columns of [`summary`], from `calibrations c`.
pub const SUMMARY_COLUMNS: &str = concat!(
    "c.id, c.sensor_id, c.station_id, c.performed_at, c.received_at, \
     c.unit, c.model::text AS model, c.runs, c.coefficients::text AS coefficients, \
     c.std_errors::text AS std_errors, c.sensor_type, c.verdict, c.due_at, \
     c.expanded::text AS expanded, c.triad::text AS triad, c.thermal::text AS thermal, ",
    crate::state_sql!(),
    " AS state"
);

/// A calibration summary from a row holding [`SUMMARY_COLUMNS`].
pub fn summary(row: &Row) -> Result<CalibrationSummary, StoreError> {
    let (thermal, thermal_triad) = crate::domain::thermal::AnyModel::split(optional_json::<
        crate::domain::thermal::AnyModel,
    >(row, "thermal")?);
    Ok(CalibrationSummary {
        id: get(row, "id")?,
        sensor_id: get(row, "sensor_id")?,
        station_id: get(row, "station_id")?,
        performed_at: timestamp(row, "performed_at")?,
        received_at: timestamp(row, "received_at")?,
        unit: get(row, "unit")?,
        model: json::<Model>(row, "model")?,
        runs: usize::try_from(get::<i32>(row, "runs")?).map_err(|e| decode("runs", e))?,
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
     c.unit, c.model::text AS model, c.runs, c.coefficients::text AS coefficients, \
     c.std_errors::text AS std_errors, c.sensor_type, c.verdict, c.due_at, \
     c.expanded::text AS expanded, c.triad::text AS triad, c.thermal::text AS thermal, c.result, c.submission, c.content_type, c.submitted_by, ",
    crate::state_sql!(),
    " AS state"
);

/// A whole calibration from a row holding [`RECORD_COLUMNS`].
pub fn record(row: &Row) -> Result<NewCalibration, StoreError> {
    let s = summary(row)?;
    Ok(NewCalibration {
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
        result: bytes::Bytes::from(get::<String>(row, "result")?),
        submission: bytes::Bytes::from(get::<Vec<u8>>(row, "submission")?),
        content_type: get(row, "content_type")?,
        submitted_by: get(row, "submitted_by")?,
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

/// The sensor columns beside [`SUMMARY_COLUMNS`] of its latest calibration,
/// with the status computed at `$1` (now) and `$2` (now + 30 days).
pub fn sensor_query(filter: &str) -> String {
    format!(
        "SELECT s.calibration_count, s.first_performed_at, s.latest_performed_at, \
         s.sensor_type AS assigned_type, s.latest_verdict, s.latest_due_at, {} AS status, \
         {SUMMARY_COLUMNS} \
         FROM sensors s JOIN calibrations c ON c.id = s.latest_calibration_id {filter}",
        Status::sql("$1", "$2")
    )
}

/// A sensor summary from a row of [`sensor_query`].
pub fn sensor(row: &Row) -> Result<SensorSummary, StoreError> {
    let latest = summary(row)?;
    let status: &str = get(row, "status")?;
    Ok(SensorSummary {
        sensor_id: latest.sensor_id.clone(),
        calibration_count: count(row, "calibration_count")?,
        first_performed_at: timestamp(row, "first_performed_at")?,
        latest_performed_at: timestamp(row, "latest_performed_at")?,
        sensor_type: get(row, "assigned_type")?,
        latest_verdict: verdict(row, "latest_verdict")?,
        due_at: optional_timestamp(row, "latest_due_at")?,
        status: Status::parse(status).ok_or_else(|| decode("status", "not a status"))?,
        latest,
    })
}

/// A sensor's row as the sensors' upsert answers it
/// ([`crate::store::SENSOR_ROW`]).
pub fn sensor_row(row: &Row) -> Result<SensorRow, StoreError> {
    Ok(SensorRow {
        sensor_id: get(row, "sensor_id")?,
        calibration_count: count(row, "calibration_count")?,
        first_performed_at: timestamp(row, "first_performed_at")?,
        latest_performed_at: timestamp(row, "latest_performed_at")?,
        latest_calibration_id: get(row, "latest_calibration_id")?,
        sensor_type: get(row, "sensor_type")?,
        latest_verdict: verdict(row, "latest_verdict")?,
        due_at: optional_timestamp(row, "latest_due_at")?,
    })
}

/// The columns of [`token`].
pub const TOKEN_COLUMNS: &str =
    "id, secret_hash, role, station_id, label, created_at, revoked_at, holder";

/// A token from a row holding [`TOKEN_COLUMNS`].
pub fn token(row: &Row) -> Result<TokenRecord, StoreError> {
    let role: &str = get(row, "role")?;
    Ok(TokenRecord {
        id: get(row, "id")?,
        secret_hash: get(row, "secret_hash")?,
        role: Role::parse(role).ok_or_else(|| decode("role", "not a role"))?,
        station_id: get(row, "station_id")?,
        label: get(row, "label")?,
        holder: get(row, "holder")?,
        created_at: timestamp(row, "created_at")?,
        revoked_at: optional_timestamp(row, "revoked_at")?,
    })
}

/// A calibration's state, from the column `state`.
pub fn state(row: &Row) -> Result<State, StoreError> {
    let text: &str = get(row, "state")?;
    State::parse(text).ok_or_else(|| decode("state", "not a state"))
}

/// A signature, from a row of `signatures`.
pub fn signature(row: &Row) -> Result<Signature, StoreError> {
    let action: &str = get(row, "action")?;
    let role: &str = get(row, "role")?;
    Ok(Signature {
        seq: u32::try_from(get::<i32>(row, "seq")?).map_err(|e| decode("seq", e))?,
        action: Action::parse(action).ok_or_else(|| decode("action", "not an action"))?,
        state: state(row)?,
        meaning: get(row, "meaning")?,
        token_id: get(row, "token_id")?,
        role: Role::parse(role).ok_or_else(|| decode("role", "not a role"))?,
        holder: get(row, "holder")?,
        signed_at: timestamp(row, "signed_at")?,
        comment: get(row, "comment")?,
        superseded_by: get(row, "superseded_by")?,
    })
}

/// A nonconformity of a standard, from its row.
pub fn nonconformity(r: &tokio_postgres::Row) -> Result<Nonconformity, StoreError> {
    let at = |column: &str| -> Result<Timestamp, StoreError> {
        Ok(Timestamp::from_datetime(get::<time::OffsetDateTime>(
            r, column,
        )?))
    };
    Ok(Nonconformity {
        id: get(r, "id")?,
        standard_id: get(r, "standard_id")?,
        found_at: at("found_at")?,
        last_known_good_at: get::<Option<time::OffsetDateTime>>(r, "last_known_good_at")?
            .map(Timestamp::from_datetime),
        window_from: at("window_from")?,
        reason: get(r, "reason")?,
        recorded_at: at("recorded_at")?,
        recorded_by: Actor {
            token_id: get(r, "token_id")?,
            role: get(r, "role")?,
            holder: get(r, "holder")?,
        },
    })
}

/// What a row of `audit` or `audit_pending` records of its act: when, by
/// whom, what, to what, the change.
pub fn event(r: &tokio_postgres::Row) -> Result<Event, StoreError> {
    Ok(Event {
        at: Timestamp::from_datetime(get::<time::OffsetDateTime>(r, "at")?),
        actor: Actor {
            token_id: get(r, "token_id")?,
            role: get(r, "role")?,
            holder: get(r, "holder")?,
        },
        action: get(r, "action")?,
        object: get(r, "object")?,
        change: get(r, "change")?,
    })
}
