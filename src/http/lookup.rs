//! Reads the handlers and pages share: a sensor by id (404 naming it when
//! it is unknown, or its id could not be valid), the id of its latest
//! calibration, and the query of the fleet's list.

use serde::Deserialize;
use utoipa::IntoParams;
use uuid::Uuid;

use super::AppState;
use super::problem::Problem;
use super::query::limit;
use crate::domain::limits::MAX_ID_CHARS;
use crate::domain::status::Status;
use crate::domain::text::{Chars, check_str, echo};
use crate::domain::timestamp::Timestamp;
use crate::store::{SensorQuery, SensorSummary};

pub fn unknown_sensor(sensor_id: &str) -> Problem {
    Problem::not_found(format!(
        "no sensor `{}` has a calibration in use (it was never calibrated, or every \
         calibration of it was rejected, withdrawn or superseded)",
        echo(sensor_id)
    ))
}

/// Looks a sensor up (its status as of now); ids that cannot be valid are
/// simply not found.
pub async fn sensor(state: &AppState, sensor_id: &str) -> Result<SensorSummary, Problem> {
    if check_str(sensor_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(unknown_sensor(sensor_id));
    }
    state
        .store
        .sensor(sensor_id.to_owned(), Timestamp::now())
        .await?
        .ok_or_else(|| unknown_sensor(sensor_id))
}

/// The id and state of a sensor's latest calibration, or 404.
pub async fn latest_id(
    state: &AppState,
    sensor_id: &str,
) -> Result<(Uuid, crate::domain::review::State), Problem> {
    if check_str(sensor_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(unknown_sensor(sensor_id));
    }
    state
        .store
        .latest_calibration_id(sensor_id.to_owned())
        .await?
        .ok_or_else(|| unknown_sensor(sensor_id))
}

/// The query of `GET /v1/sensors`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct SensorListQuery {
    /// Page size.
    #[param(value_type = Option<u32>, minimum = 1, maximum = 500, default = 50)]
    limit: Option<String>,
    /// The `next` cursor of the previous page (the last sensor id it held).
    #[param(value_type = Option<crate::domain::schema::Identifier>)]
    after: Option<String>,
    /// Only sensors of this status: `failed`, `overdue`, `due_soon`, `ok`
    /// or `unknown`.
    #[param(value_type = Option<Status>)]
    status: Option<String>,
    /// Only sensors whose id contains this text (ASCII case-insensitive;
    /// 1–64 characters of `[A-Za-z0-9._:-]`).
    #[param(value_type = Option<String>, min_length = 1, max_length = 64, pattern = "^[A-Za-z0-9._:-]{1,64}$")]
    search: Option<String>,
}

impl SensorListQuery {
    /// The store query of one page (one more than `limit`, to know whether
    /// another page follows), and the page size.
    pub(crate) fn store_query(self) -> Result<(SensorQuery, usize), Problem> {
        let limit = limit(self.limit.as_deref())?;
        let after = self
            .after
            .map(|a| {
                check_str(&a, MAX_ID_CHARS, Chars::Identifier)
                    .map(|()| a)
                    .map_err(|e| {
                        Problem::bad_parameter("after", format!("is not a sensor id: it {e}"))
                    })
            })
            .transpose()?;
        let status = self
            .status
            .map(|s| {
                Status::parse(&s).ok_or_else(|| {
                    Problem::bad_parameter(
                        "status",
                        "must be one of failed, overdue, due_soon, ok, unknown",
                    )
                })
            })
            .transpose()?;
        let search = self
            .search
            .map(|s| {
                let plain = (1..=MAX_ID_CHARS).contains(&s.chars().count())
                    && s.chars()
                        .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | ':' | '-'));
                if plain {
                    Ok(s)
                } else {
                    Err(Problem::bad_parameter(
                        "search",
                        format!("must be 1–{MAX_ID_CHARS} characters of A–Z, a–z, 0–9, `.`, `_`, `:`, `-`"),
                    ))
                }
            })
            .transpose()?;
        Ok((
            SensorQuery {
                after,
                status,
                search,
                now: Timestamp::now(),
                limit: limit + 1,
            },
            limit,
        ))
    }
}

/// Refuses (400) an id in the path that cannot be one.
pub fn path_identifier(id: &str, what: &str) -> Result<(), Problem> {
    check_str(id, MAX_ID_CHARS, Chars::Identifier)
        .map_err(|why| Problem::bad_request(format!("the {what} id {why}")))
}
