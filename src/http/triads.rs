//! Stored triad calibrations (issue 30): `POST /v1/calibrations/triad`
//! computes a triad as `POST /v1/identify/triad` does and stores it as one
//! calibration of its sensor (its elements beside the single-axis columns,
//! [`TriadElements`]); `GET /v1/calibrations/{id}/export` answers a stored
//! triad in the form firmware loads. A sensor's calibrations are all of one
//! kind ([`same_kind`]).

use accelcal_core::{Model, Term, TermMap};
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::Response;
use bytes::Bytes;
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use uuid::Uuid;

use super::auth::{require, station};
use super::body::Body;
use super::calibrations::{claim, created, idempotency_key, replay};
use super::problem::{Kind, Problem};
use super::query::Params;
use super::triad::{file, read};
use super::{AppState, path_id};
use crate::domain::auth::{Principal, Role};
use crate::domain::field::{Invalid, Loc};
use crate::domain::review::Basis;
use crate::domain::submission::performed_when;
use crate::domain::text::echo;
use crate::domain::timestamp::Timestamp;
use crate::domain::triad::{Form, TriadResult, compute};
use crate::domain::triad_export::{Exported, Format};
use crate::store::{CalibrationSummary, NewCalibration, Stored, TriadElements};

/// A stored triad's result document (`POST /v1/calibrations/triad`, and
/// `GET /v1/calibrations/{id}` for a triad): the triad's result with what
/// storing it added.
#[derive(Debug, Serialize, ToSchema)]
pub struct StoredTriad {
    /// The calibration's id.
    pub id: Uuid,
    /// The submitting station, if known.
    pub station_id: Option<String>,
    /// When the test was performed.
    pub performed_at: Timestamp,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// The triad.
    #[serde(flatten)]
    pub result: TriadResult,
}

/// What a triad's result stores of itself.
fn elements(r: &TriadResult) -> TriadElements {
    TriadElements {
        method: r.method.to_owned(),
        b: r.b,
        b_std_errors: r.b_std_errors,
        s: r.s,
        s_std_errors: r.s_std_errors,
        t: r.t,
        t_std_errors: r.t_std_errors,
    }
}

/// Refuses a calibration of the other kind for `sensor_id`: a sensor's
/// calibrations are all single-axis or all a triad's (`triad`), so that
/// its history, stability and compensation read one kind. The sensor is
/// judged by its latest calibration that counts.
pub async fn same_kind(
    state: &AppState,
    sensor_id: &str,
    triad: bool,
    now: Timestamp,
) -> Result<(), Problem> {
    let Some(sensor) = state.store.sensor(sensor_id.to_owned(), now).await? else {
        return Ok(());
    };
    wrong_kind(sensor_id, sensor.latest.triad.is_some(), triad)
}

/// The refusal of a `triad` (or single-axis) submission for a sensor whose
/// calibrations are of the other kind (`is_triad`).
pub fn wrong_kind(sensor_id: &str, is_triad: bool, triad: bool) -> Result<(), Problem> {
    if is_triad == triad {
        return Ok(());
    }
    let id = echo(sensor_id);
    let why = if triad {
        format!(
            "sensor `{id}` holds single-axis calibrations; a triad is calibrated under an id of \
             its own (a sensor's calibrations are all of one kind)"
        )
    } else {
        format!(
            "sensor `{id}` is a triad: its calibrations are submitted with \
             POST /v1/calibrations/triad"
        )
    };
    Err(Problem::new(Kind::WrongKind, why.clone())
        .with_errors(Invalid::one(Loc::Root.key("sensor_id"), why)))
}

/// Refuses `what` (a single-axis document or act) of a triad's
/// calibration `c`, saying what there is instead.
pub fn single_axis(c: &CalibrationSummary, what: &str) -> Result<(), Problem> {
    if c.triad.is_none() {
        return Ok(());
    }
    Err(Problem::new(
        Kind::WrongKind,
        format!(
            "calibration {} is a triad's: {what} is for single-axis calibrations; a triad's \
             result is at GET /v1/calibrations/{}, its firmware files at \
             GET /v1/calibrations/{}/export",
            c.id, c.id, c.id
        ),
    ))
}

/// `POST /v1/calibrations/triad`: check, compute, store durably, answer 201;
/// with an `Idempotency-Key`, at most once per key.
#[utoipa::path(
    post,
    path = "/v1/calibrations/triad",
    tag = "calibrations",
    operation_id = "submitTriad",
    summary = "Calibrate a triad (u = b + S g) and store it as a calibration of its sensor.",
    description = "The body of `POST /v1/identify/triad` (JSON or CSV) with `sensor_id` \
        required and, optionally, `station_id` and `performed_at` (CSV: `# key: value` lines). \
        Stored as one calibration of the sensor: its history, review, withdrawal, compensation \
        with triples and the firmware exports (`GET /v1/calibrations/{id}/export`) follow. A \
        sensor's calibrations are all single-axis or all a triad's (409 `wrong-kind`).",
    params(super::openapi::IdempotencyKeyHeader),
    request_body(content((String = "text/csv"), (crate::domain::triad::TriadBody = "application/json",
        example = json!({"sensor_id": "IMU-7", "unit": "m/s2", "orientations": "six_faces",
            "runs": [{"samples": [
            [[9.91, 0.02, -0.05]], [[-9.71, 0.01, -0.06]], [[0.12, 9.79, -0.04]],
            [[0.09, -9.83, -0.07]], [[0.11, 0.03, 9.75]], [[0.10, 0.00, -9.87]]]}]})))),
    responses(
        (status = 201, description = "Stored (or, for a retried Idempotency-Key, stored before).",
            body = StoredTriad,
            headers(
                ("Location" = String, description = "The calibration's URL."),
                ("Idempotent-Replayed" = String, description = "`true` when this answer replays an earlier request with the same key."),
            ),
            links(
                ("GetCalibration" = (operation_id = "getCalibration", parameters(("id" = "$response.body#/id")))),
                ("ExportCalibration" = (operation_id = "exportCalibration", parameters(("id" = "$response.body#/id")))),
            )),
        (status = 403, response = super::openapi::Forbidden),
        (status = 409, response = super::openapi::WrongKind),
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
    let key = idempotency_key(&headers, &principal, &body)?;
    let guard = match &key {
        None => None,
        Some(k) => match claim(&state, k).await? {
            Ok(guard) => Some(guard),
            Err(answered) => return Ok(answered),
        },
    };
    let received_at = Timestamp::now();
    let id = Uuid::now_v7();
    let (submission, content_type) = (body.bytes.clone(), body.content_type.clone());
    let who = principal.clone();
    let (record, view) = state
        .compute_for(body.bytes.len(), move || -> Result<_, Problem> {
            let sub = read(&body)?;
            let root = Loc::Root;
            let sensor_id = sub.sensor_id.clone().ok_or_else(|| {
                Problem::validation(Invalid::one(
                    root.key("sensor_id"),
                    "is required to store a triad (POST /v1/identify/triad computes one without)",
                ))
            })?;
            let station_id = station(&who, sub.station_id.as_deref())?;
            let performed_at = match sub.performed_at {
                None => received_at,
                Some(t) => performed_when(t, received_at).map_err(|why| {
                    Problem::validation(Invalid::one(root.key("performed_at"), why))
                })?,
            };
            let runs = match &sub.form {
                Form::Known { runs, .. } => runs.len(),
                _ => 1,
            };
            let result = compute(sub)?;
            let record = NewCalibration {
                id,
                sensor_id,
                station_id: station_id.clone(),
                performed_at,
                received_at,
                unit: result.unit.clone(),
                model: Model::new(vec![Term::K0, Term::Ki, Term::Kp, Term::Ko])
                    .map_err(|_| Problem::internal())?,
                runs,
                coefficients: TermMap(Vec::new()),
                std_errors: TermMap(Vec::new()),
                result: Bytes::new(),
                submission,
                content_type,
                submitted_by: who.id.clone(),
                sensor_type: None,
                assigns_type: false,
                verdict: None,
                due_at: None,
                expanded: None,
                triad: Some(elements(&result)),
            };
            let view = StoredTriad {
                id,
                station_id,
                performed_at,
                received_at,
                result,
            };
            Ok((record, view))
        })
        .await??;
    same_kind(&state, &record.sensor_id, true, received_at).await?;
    let result = Bytes::from(serde_json::to_vec(&view).map_err(|err| {
        tracing::error!(error = %err, "a triad's result did not serialise");
        Problem::internal()
    })?);
    let sensor_id = record.sensor_id.clone();
    let stored = state
        .store
        .insert_calibration(
            NewCalibration {
                result: result.clone(),
                ..record
            },
            key,
        )
        .await?;
    if let Some(g) = guard {
        g.done();
    }
    match stored {
        Stored::New => {
            tracing::info!(calibration_id = %id, sensor_id = %sensor_id, "triad calibration stored");
            Ok(created(id, result))
        }
        Stored::Existing(first) => replay(&state, first).await,
    }
}

/// The query of `GET /v1/calibrations/{id}/export`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ExportQuery {
    /// `json` (b, S, T and the convention), `c` (a header), `px4` or
    /// `ardupilot` (parameter files).
    #[param(pattern = "^(json|c|px4|ardupilot)$")]
    pub format: String,
}

/// `GET /v1/calibrations/{id}/export?format=…`: a stored triad as a file.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}/export",
    tag = "calibrations",
    operation_id = "exportCalibration",
    summary = "A stored triad in the form firmware loads.",
    description = "`json` (b, S, T, the model and convention, units), `c` (a header with the \
        arrays and the equation in a comment), `px4` (`CAL_ACC0_*OFF`, `CAL_ACC0_*SCALE`) or \
        `ardupilot` (`INS_ACCOFFS_*`, `INS_ACCSCAL_*`). PX4 and ArduPilot carry only a diagonal: \
        an off-diagonal term of T above 1 % of its row's diagonal is refused (422), a smaller \
        one named in the file; both need outputs in m/s² or g. A calibration that no longer \
        counts (rejected, withdrawn, superseded) is not exported (409); a single-axis one has \
        no export (409 `wrong-kind`).",
    params(super::openapi::CalibrationIdPath, ExportQuery),
    responses(
        (status = 200, description = "The file, named for download.",
            content((super::triad::TriadExport = "application/json"), (String = "text/plain"), (String = "text/x-c"))),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::WrongKind),
        super::openapi::Always,
        (status = 422, response = super::openapi::Invalid),
    )
)]
pub async fn export(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
    Params(q): Params<ExportQuery>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    exported(&state, id, &q.format).await
}

/// Calibration `id` as a firmware file in `format` (what the export route
/// and the page's download answer).
pub async fn exported(state: &AppState, id: Uuid, format: &str) -> Result<Response, Problem> {
    let format = Format::parse(format)
        .ok_or_else(|| Problem::bad_parameter("format", "must be json, c, px4 or ardupilot"))?;
    let c = state
        .store
        .calibration_summary(id)
        .await?
        .ok_or_else(|| Problem::not_found(format!("no calibration with id `{id}`")))?;
    let Some(t) = &c.triad else {
        return Err(Problem::new(
            Kind::WrongKind,
            format!(
                "calibration {id} is single-axis: its coefficients are at \
                 GET /v1/calibrations/{id}; exports are for triads"
            ),
        ));
    };
    if !c.state.counts(Basis::NotRejected) {
        return Err(Problem::new(
            Kind::StateConflict,
            format!(
                "calibration {id} is {}: it no longer counts and is not exported; the sensor's \
                 latest is at GET /v1/sensors/{}",
                c.state.as_str(),
                echo(&c.sensor_id)
            ),
        ));
    }
    let source = format!(
        "triad {}, calibration {id} performed {} ({}), accelcal {}",
        c.sensor_id,
        c.performed_at,
        c.state.as_str(),
        env!("CARGO_PKG_VERSION")
    );
    file(
        &Exported {
            unit: &c.unit,
            b: t.b,
            s: t.s,
            t: t.t,
            source,
        },
        format,
    )
}
