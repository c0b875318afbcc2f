//! `POST /v1/calibrations` and reading calibrations back.

use std::sync::Arc;

use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderName, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use sha2::{Digest, Sha256};
use uuid::Uuid;

use super::extract::{Body, Media};
use super::problem::Problem;
use super::{AppState, evaluate, path_id};
use crate::auth::{Principal, Role};
use crate::store::{Claim, IdempotencyKey, NewCalibration, Store, Stored};
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

/// The `Idempotency-Key` request header.
pub static IDEMPOTENCY_KEY: HeaderName = HeaderName::from_static("idempotency-key");

/// The idempotency key of a request, if it sent one: 1–255 visible ASCII
/// characters, scoped to the principal, fingerprinted with the body.
fn idempotency_key(
    headers: &HeaderMap,
    principal: &Principal,
    body: &Body,
) -> Result<Option<IdempotencyKey>, Problem> {
    let mut values = headers.get_all(&IDEMPOTENCY_KEY).iter();
    let Some(value) = values.next() else {
        return Ok(None);
    };
    if values.next().is_some() {
        return Err(Problem::bad_parameter(
            "Idempotency-Key",
            "is sent more than once",
        ));
    }
    let key = value
        .to_str()
        .ok()
        .filter(|k| (1..=255).contains(&k.len()) && k.bytes().all(|b| (0x21..=0x7e).contains(&b)))
        .ok_or_else(|| {
            Problem::bad_parameter(
                "Idempotency-Key",
                "must be 1 to 255 visible ASCII characters",
            )
        })?;
    let mut hash = Sha256::new();
    hash.update(match body.media {
        Media::Json => b"json\n".as_slice(),
        Media::Csv => b"csv\n".as_slice(),
    });
    hash.update(&body.bytes);
    Ok(Some(IdempotencyKey {
        principal: principal.id.clone(),
        key: key.to_owned(),
        request_hash: hash.finalize().into(),
    }))
}

/// Holds a claimed idempotency key; releases it if the request ends (error,
/// or the client went away) without storing a calibration.
struct KeyGuard {
    store: Arc<dyn Store>,
    key: Option<IdempotencyKey>,
}

impl KeyGuard {
    fn done(mut self) {
        self.key = None;
    }
}

impl Drop for KeyGuard {
    fn drop(&mut self) {
        if let Some(k) = self.key.take()
            && let Ok(rt) = tokio::runtime::Handle::try_current()
        {
            let store = self.store.clone();
            rt.spawn(async move {
                if let Err(e) = store.release_key(k.principal, k.key).await {
                    tracing::warn!(error = %e, "could not release an idempotency key; its lease will expire");
                }
            });
        }
    }
}

/// Answers a retry with the calibration its key already stored.
async fn replay(state: &AppState, id: Uuid) -> Result<Response, Problem> {
    let result = state.store.calibration_result(id).await?.ok_or_else(|| {
        crate::store::StoreError::Corrupt(format!("idempotency key names missing calibration {id}"))
    })?;
    let mut res = created(id, result);
    res.headers_mut().insert(
        HeaderName::from_static("idempotent-replayed"),
        HeaderValue::from_static("true"),
    );
    Ok(res)
}

/// `POST /v1/calibrations`: check, identify, fuse, store durably, answer 201;
/// with an `Idempotency-Key`, at most once per key.
pub async fn submit(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    principal.require(Role::Station)?;
    let key = idempotency_key(&headers, &principal, &body)?;
    let guard = match &key {
        None => None,
        Some(k) => {
            let now = Timestamp::now();
            let lease = now.plus_seconds(state.limits.request_timeout.as_secs() as i64 + 30);
            match state.store.claim_key(k.clone(), now, lease).await? {
                Claim::Fresh => Some(KeyGuard {
                    store: state.store.clone(),
                    key: Some(k.clone()),
                }),
                Claim::Done(id) => return replay(&state, id).await,
                Claim::InFlight => {
                    return Err(Problem {
                        retry_after: Some(1),
                        ..Problem::new(
                            StatusCode::CONFLICT,
                            "in-flight",
                            "Request in progress",
                            "a request with this Idempotency-Key is still being processed; retry shortly",
                        )
                    });
                }
                Claim::Mismatch => {
                    return Err(Problem {
                        parameter: Some("Idempotency-Key".into()),
                        ..Problem::new(
                            StatusCode::UNPROCESSABLE_ENTITY,
                            "idempotency-key-reused",
                            "Idempotency-Key reused",
                            "this Idempotency-Key was already used with a different request body",
                        )
                    });
                }
            }
        }
    };
    let value = body.submission()?;
    let received_at = Timestamp::now();
    let evaluated = evaluate(value, received_at).await?;
    let station_id = station(&principal, evaluated.submission.station_id.as_deref())?;
    let id = Uuid::now_v7();
    let rec = record(&evaluated, id, station_id, received_at, &body, &principal);
    let result = rec.result.clone();
    let stored = state.store.insert_calibration(rec, key).await?;
    if let Some(g) = guard {
        g.done();
    }
    match stored {
        Stored::New => {
            tracing::info!(calibration_id = %id, sensor_id = %evaluated.submission.sensor_id, "calibration stored");
            Ok(created(id, result))
        }
        Stored::Existing(first) => replay(&state, first).await,
    }
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

fn unknown(id: Uuid) -> Problem {
    Problem::not_found(format!("no calibration with id `{id}`"))
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
        .ok_or_else(|| unknown(id))?;
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
        .ok_or_else(|| unknown(id))?;
    let content_type = HeaderValue::from_str(&s.content_type)
        .unwrap_or(HeaderValue::from_static("application/octet-stream"));
    Ok(([(header::CONTENT_TYPE, content_type)], s.body).into_response())
}
