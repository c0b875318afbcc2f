//! `POST /v1/calibrations` and reading calibrations back.

use axum::extract::{Path, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use uuid::Uuid;

use super::extract::Body;
use super::problem::Problem;
use super::{AppState, evaluate, path_id};
use crate::auth::{Principal, Role};
use crate::store::NewCalibration;
use crate::submission::{Evaluated, ResultView};
use crate::timestamp::Timestamp;

/// The station recorded on a submission: a bound token's station, which the
/// body may repeat but not contradict; otherwise the body's `station_id`.
fn station(principal: &Principal, claimed: Option<&str>) -> Result<Option<String>, Problem> {
    match (&principal.station_id, claimed) {
        (Some(bound), Some(claimed)) if bound != claimed => Err(Problem::forbidden(format!(
            "this token is bound to station `{bound}` and cannot submit as `{claimed}`"
        ))),
        (Some(bound), _) => Ok(Some(bound.clone())),
        (None, claimed) => Ok(claimed.map(str::to_owned)),
    }
}

fn record(
    e: &Evaluated,
    id: Uuid,
    station_id: Option<String>,
    received_at: Timestamp,
    body: &Body,
    principal: &Principal,
) -> NewCalibration {
    let view = ResultView::new(e, Some(id), station_id.as_deref(), received_at);
    let fused = &e.calibration.fused;
    NewCalibration {
        id,
        sensor_id: e.submission.sensor_id.clone(),
        performed_at: view.performed_at,
        received_at,
        unit: e.submission.unit.clone(),
        model: json(e.submission.test.model()),
        runs: e.calibration.runs.len(),
        coefficients: json(&fused.coefficients),
        std_errors: json(&fused.std_errors),
        result: json(&view),
        submission: body.bytes.to_vec(),
        content_type: body.content_type.clone(),
        submitted_by: principal.id.clone(),
        station_id,
    }
}

/// Compact JSON text of a result part (every number in a result is finite).
fn json<T: serde::Serialize + ?Sized>(v: &T) -> String {
    serde_json::to_string(v).expect("results serialise")
}

/// `POST /v1/calibrations`: check, identify, fuse, store durably, answer 201.
pub async fn submit(
    State(state): State<AppState>,
    principal: Principal,
    body: Body,
) -> Result<Response, Problem> {
    principal.require(Role::Station)?;
    let value = body.submission()?;
    let received_at = Timestamp::now();
    let evaluated = evaluate(value, received_at).await?;
    let station_id = station(&principal, evaluated.submission.station_id.as_deref())?;
    let id = Uuid::now_v7();
    let rec = record(&evaluated, id, station_id, received_at, &body, &principal);
    let result = rec.result.clone();
    state.store.insert_calibration(rec).await?;
    tracing::info!(calibration_id = %id, sensor_id = %evaluated.submission.sensor_id, "calibration stored");
    Ok(created(id, result))
}

/// A 201 answer for a stored calibration.
pub(crate) fn created(id: Uuid, result: String) -> Response {
    let location = HeaderValue::from_str(&format!("/v1/calibrations/{id}")).expect("ASCII");
    (
        StatusCode::CREATED,
        [
            (header::LOCATION, location),
            (
                header::CONTENT_TYPE,
                HeaderValue::from_static("application/json"),
            ),
        ],
        result,
    )
        .into_response()
}

/// `GET /v1/calibrations/{id}`: the stored result document.
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    principal.require(Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    let result = state
        .store
        .calibration_result(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    Ok(([(header::CONTENT_TYPE, "application/json")], result).into_response())
}

/// `GET /v1/calibrations/{id}/submission`: the body as submitted, byte for byte.
pub async fn submission(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    principal.require(Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    let s = state
        .store
        .submission(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    let content_type = HeaderValue::from_str(&s.content_type)
        .unwrap_or(HeaderValue::from_static("application/octet-stream"));
    Ok(([(header::CONTENT_TYPE, content_type)], s.body).into_response())
}
