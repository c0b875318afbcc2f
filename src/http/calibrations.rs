//! `POST /v1/calibrations` and reading calibrations back.

use std::sync::Arc;

use axum::extract::{Path, RawQuery, State};
use axum::http::{HeaderMap, HeaderName, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use sha2::{Digest, Sha256};
use uuid::Uuid;

use super::auth::require;
use super::body::Body;
use super::evaluation::assess;
use super::problem::{Kind, Problem};
use super::{AppState, path_id};
use crate::domain::auth::{Principal, Role};
use crate::domain::submission::Media;
use crate::domain::timestamp::Timestamp;
use crate::store::{Claim, IdempotencyKey, NewCalibration, Store, StoreError, Stored};

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
        holder: Uuid::now_v7(),
    }))
}

/// Holds a claimed idempotency key; releases it if the request ends (error,
/// or the client went away) without storing a calibration.
pub(super) struct KeyGuard {
    store: Arc<dyn Store>,
    key: Option<IdempotencyKey>,
}

impl KeyGuard {
    pub(super) fn done(mut self) {
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
                if let Err(e) = store.release_key(k).await {
                    tracing::warn!(error = %e.chain(), "could not release an idempotency key; its lease will expire");
                }
            });
        }
    }
}

/// How long a key's lease outlasts its request's deadline: time for the
/// request's last write to land. A lease that expires anyway (a crashed
/// replica's) is taken over; the key's completion is guarded in the store,
/// so even then one key stores one calibration.
const LEASE_MARGIN_SECONDS: i64 = 5;

/// Claims the request's key; answers a retry or a conflict at once.
async fn claim(
    state: &AppState,
    key: &IdempotencyKey,
) -> Result<Result<KeyGuard, Response>, Problem> {
    let now = Timestamp::now();
    let lease =
        now.plus_seconds(state.limits.request_timeout.as_secs() as i64 + LEASE_MARGIN_SECONDS);
    Ok(
        match state.store.claim_key(key.clone(), now, lease).await? {
            Claim::Fresh => Ok(KeyGuard {
                store: state.store.clone(),
                key: Some(key.clone()),
            }),
            Claim::Done(id) => Err(replay(state, id).await?),
            Claim::InFlight => {
                return Err(Problem::new(
                    Kind::InFlight,
                    "a request with this Idempotency-Key is still being processed; retry shortly",
                )
                .retry_after(1));
            }
            Claim::Mismatch => {
                return Err(Problem::new(
                    Kind::IdempotencyKeyReused,
                    "this Idempotency-Key was already used with a different request body",
                )
                .naming("Idempotency-Key"));
            }
        },
    )
}

/// Answers a retry with the calibration its key already stored.
async fn replay(state: &AppState, id: Uuid) -> Result<Response, Problem> {
    let result = state.store.calibration_result(id).await?.ok_or_else(|| {
        StoreError::corrupt("idempotency key", format!("names missing calibration {id}"))
    })?;
    let mut res = created(id, result);
    res.headers_mut().insert(
        HeaderName::from_static("idempotent-replayed"),
        HeaderValue::from_static("true"),
    );
    Ok(res)
}

/// A storing request's `Idempotency-Key`, claimed: go on with the key and
/// its guard (none without a key), or the answer already due (a retry of a
/// stored request, or a conflict). Single-axis and triad submissions alike.
pub(super) async fn claimed(
    state: &AppState,
    headers: &HeaderMap,
    principal: &Principal,
    body: &Body,
) -> Result<Result<(Option<IdempotencyKey>, Option<KeyGuard>), Response>, Problem> {
    let key = idempotency_key(headers, principal, body)?;
    let guard = match &key {
        None => None,
        Some(k) => match claim(state, k).await? {
            Ok(guard) => Some(guard),
            Err(answered) => return Ok(Err(answered)),
        },
    };
    Ok(Ok((key, guard)))
}

/// Stores `rec` (its result document `result`) under `key`, releases the
/// key's guard once stored, and answers 201 — or, when a concurrent request
/// with the same key stored first, replays that one.
pub(super) async fn store(
    state: &AppState,
    rec: NewCalibration,
    key: Option<IdempotencyKey>,
    guard: Option<KeyGuard>,
) -> Result<Response, Problem> {
    let (id, sensor_id, verdict, result) = (
        rec.id,
        rec.sensor_id.clone(),
        rec.verdict,
        rec.result.clone(),
    );
    let kind = if rec.triad.is_some() {
        "triad"
    } else {
        "single-axis"
    };
    let stored = state.store.insert_calibration(rec, key).await?;
    if let Some(g) = guard {
        g.done();
    }
    match stored {
        Stored::New => {
            tracing::info!(calibration_id = %id, sensor_id = %sensor_id, kind, "calibration stored");
            if let Some(v) = verdict {
                metrics::counter!("accelcal_verdicts_total", "verdict" => v.as_str()).increment(1);
            }
            Ok(created(id, result))
        }
        Stored::Existing(first) => replay(state, first).await,
    }
}

/// `POST /v1/calibrations`: check, identify, fuse, store durably, answer 201;
/// with an `Idempotency-Key`, at most once per key.
#[utoipa::path(
    post,
    path = "/v1/calibrations",
    tag = "calibrations",
    operation_id = "submitCalibration",
    description = include_str!("docs/submit.md"),
    params(super::openapi::IdempotencyKeyHeader),
    request_body(content(
        (super::openapi::SubmissionSchema = "application/json"),
        (super::openapi::RawBodySchema = "text/csv"),
    )),
    responses(
        (status = 201, description = "Stored (or, for a retried Idempotency-Key, stored before).",
            body = super::openapi::StoredCalibrationSchema,
            headers(
                ("Location" = String, description = "The calibration's URL."),
                ("Idempotent-Replayed" = String, description = "`true` when this answer replays an earlier request with the same key."),
            ),
            links(
                ("GetCalibration" = (operation_id = "getCalibration", parameters(("id" = "$response.body#/id")))),
                ("GetSubmission" = (operation_id = "getSubmission", parameters(("id" = "$response.body#/id")))),
                ("GetSensor" = (operation_id = "getSensor", parameters(("sensor_id" = "$response.body#/sensor_id")))),
            )),
        (status = 403, response = super::openapi::Forbidden),
        (status = 408, response = super::openapi::ProblemResponse),
        (status = 409, response = super::openapi::ProblemResponse),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn submit(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Station)?;
    let (key, guard) = match claimed(&state, &headers, &principal, &body).await? {
        Ok(claimed) => claimed,
        Err(answered) => return Ok(answered),
    };
    let received_at = Timestamp::now();
    let id = Uuid::now_v7();
    let assessed = assess(&state, &principal, body, received_at, Some(id), None).await?;
    let Some(rec) = assessed.record else {
        return Err(Problem::internal());
    };
    store(&state, rec, key, guard).await
}

/// A 201 answer for a stored calibration.
pub(crate) fn created(id: Uuid, result: Bytes) -> Response {
    let location = HeaderValue::from_str(&format!("/v1/calibrations/{id}"))
        .unwrap_or(HeaderValue::from_static("/v1/calibrations"));
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

/// `GET /v1/calibrations/{id}`: the stored result document, as stored.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}",
    tag = "calibrations",
    operation_id = "getCalibration",
    params(super::openapi::CalibrationIdPath),
    responses(
        (status = 200, description = "The result, as answered when it was submitted: a single-axis \
            calibration's, or a triad's (`kind: triad`).", body = super::openapi::StoredResultSchema),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    let result = state
        .store
        .calibration_result(id)
        .await?
        .ok_or_else(|| unknown(id))?;
    Ok(([(header::CONTENT_TYPE, "application/json")], result).into_response())
}

/// `GET /v1/calibrations/{id}/submission`: the body as submitted, byte for byte.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}/submission",
    tag = "calibrations",
    operation_id = "getSubmission",
    params(super::openapi::CalibrationIdPath),
    responses(
        (status = 200, description = "The body as submitted (decompressed, if it was sent gzip-encoded).",
            content((super::openapi::RawBodySchema = "text/csv"), (serde_json::Value = "application/json"))),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn submission(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
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

/// The query of `GET /v1/calibrations/{id}/certificate`.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub struct CertificateQuery {
    /// The revision of the issued certificate to answer (1 as issued, 2 for
    /// the first amendment, …); the latest without.
    #[param(minimum = 1)]
    #[allow(dead_code)]
    revision: Option<u32>,
}

/// `GET /v1/calibrations/{id}/certificate`: the certificate as issued.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}/certificate",
    tag = "calibrations",
    operation_id = "getCertificate",
    summary = "The calibration certificate: an HTML document that prints on A4, or with \
        `Accept: application/xml` a Digital Calibration Certificate (PTB DCC 3.3.0).",
    description = "An approved calibration's certificate is issued with the approval and \
        answered as issued ever after — the DCC byte for byte — whatever changes later to the \
        item, the customer or the laboratory; changing it is an amendment \
        (`POST …/amend`), a new revision of the same number, and `?revision=N` answers any \
        revision (`Certificate-Revision` says which). A calibration withdrawn, superseded or \
        held since is answered with that notice before the issued document. One not \
        approved is rendered on request as a draft (`Certificate-Revision: draft`), and has \
        no DCC (409).",
    params(super::openapi::CalibrationIdPath, CertificateQuery),
    responses(
        (status = 200, description = "The certificate: sensor, type, station and stand, times, method, \
            fused coefficients with expanded uncertainty, decision, as found, due date, the SHA-256 of \
            the stored submission, the accelcal version and its own URL.",
            content((String = "text/html"), (String = "application/xml")),
            headers(("Certificate-Revision" = String, description = "The revision answered, or `draft`."))),
        (status = 400, response = super::openapi::BadRequest),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::Incomplete),
        super::openapi::Always,
    )
)]
pub async fn certificate(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    Path(id): Path<String>,
    RawQuery(query): RawQuery,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    super::ui::certificate::respond(&state, &headers, &id, query.as_deref()).await
}
