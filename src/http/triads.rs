//! Stored triad calibrations (issue 30): `POST /v1/calibrations/triad`
//! computes a triad as `POST /v1/identify/triad` does — with the sensor
//! type's coverage factor and decision, the registered standards and as
//! found against the previous triad — and stores it as one calibration of
//! its sensor (its elements beside the single-axis columns,
//! [`TriadElements`]); `GET /v1/calibrations/{id}/export` answers a stored
//! triad in the form firmware loads. A sensor's calibrations are all of one
//! kind ([`wrong_kind`]).

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
use super::calibrations::{claimed, store};
use super::evaluation::{Assessed, Resolved, resolve, sensor_type};
use super::problem::{Kind, Problem};
use super::query::Params;
use super::triad::{file, read};
use super::{AppState, path_id};
use crate::domain::auth::{Principal, Role};
use crate::domain::field::{Invalid, Loc};
use crate::domain::review::{Basis, Supersedes};
use crate::domain::sensor_types::SensorType;
use crate::domain::submission::performed_when;
use crate::domain::text::echo;
use crate::domain::timestamp::Timestamp;
use crate::domain::triad::{Form, GRAVITY_MAGNITUDE, TriadResult, as_found, compute, decide_triad};
use crate::domain::triad_export::{Exported, Format};
use crate::store::{CalibrationSummary, NewCalibration, TriadElements};
use accelcal_core::gravity_fit::MIN_POSITIONS;

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
    /// The calibration this one supersedes, and why (a correction or a
    /// reprocessing).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub supersedes: Option<Supersedes>,
    /// When the sensor is next due: a judged triad's performance date plus
    /// its type's interval.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub due_at: Option<Timestamp>,
    /// The triad.
    #[serde(flatten)]
    pub result: TriadResult,
}

/// Judges `r` against sensor type `t`'s limits ([`decide_triad`]), element
/// by element. A triad from the gravity magnitude is judged on the elements
/// it measures (those zero by the frame convention are not, and the note
/// says so); with exactly nine positions it has no uncertainty and is not
/// judged, saying why.
fn judge(r: &mut TriadResult, t: &SensorType) -> Result<(), Problem> {
    if t.limits.is_empty() {
        return Ok(());
    }
    match decide_triad(r, t.decision_rule, &t.limits) {
        Ok(Some(d)) => {
            if r.method == GRAVITY_MAGNITUDE {
                r.decision_note = Some(format!(
                    "S_xy, S_xz and S_yz are zero by the frame convention of a triad found from \
                     the gravity magnitude (the sensor's x axis and xy-plane define the frame): \
                     not measured, so not judged against sensor type `{}`",
                    t.type_id
                ));
            }
            r.decision = Some(d);
        }
        Ok(None) => {
            r.decision_note = Some(format!(
                "not judged against sensor type `{}`: with exactly {MIN_POSITIONS} static \
                 positions the fit from the gravity magnitude has no degree of freedom left, so \
                 no standard error and no uncertainty (hold at least {} orientations)",
                t.type_id,
                MIN_POSITIONS + 1
            ))
        }
        Err(term) => {
            return Err(Problem::validation(Invalid::one(
                Loc::Root.key("sensor_type"),
                format!(
                    "sensor type `{}` sets limits on `{term}`, which a triad does not identify \
                     (each axis's k0, ki, kp, ko: b and S)",
                    t.type_id
                ),
            )));
        }
    }
    Ok(())
}

/// As found of `r` against the sensor's previous calibration `p` (a
/// triad's, in the same unit), or why not.
fn found(r: &mut TriadResult, p: &CalibrationSummary) {
    let Some(t) = p.triad.as_ref() else {
        return; // a sensor's calibrations are of one kind: not reached
    };
    if p.unit != r.unit {
        r.as_found_note = Some(format!(
            "the previous calibration {} is in `{}`, this one in `{}`: as found compares \
             outputs in one unit",
            p.id, p.unit, r.unit
        ));
        return;
    }
    r.as_found = as_found(r, p.id, &t.model());
    if r.as_found.is_none() {
        r.as_found_note = Some(format!(
            "the previous calibration {}'s S is singular: it cannot compensate",
            p.id
        ));
    }
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
        b_expanded: r.b_expanded,
        s_expanded: r.s_expanded,
        s2: r.s2,
        s2_std_errors: r.s2_std_errors,
        s2_expanded: r.s2_expanded,
    }
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
    let (key, guard) = match claimed(&state, &headers, &principal, &body).await? {
        Ok(claimed) => claimed,
        Err(answered) => return Ok(answered),
    };
    let (id, received_at) = (Uuid::now_v7(), Timestamp::now());
    let assessed = assess(&state, &principal, body, received_at, id, None).await?;
    let Some(record) = assessed.record else {
        return Err(Problem::internal());
    };
    store(&state, record, key, guard).await
}

/// A triad body computed as it is stored under `id` — checked, with the
/// sensor type in force and its decision, the registered standards and as
/// found against the previous triad — and its result document rendered
/// once; with `supersedes`, the calibration it corrects is recorded in it.
/// What `POST /v1/calibrations/triad`, superseding and reprocessing store.
pub async fn assess(
    state: &AppState,
    principal: &Principal,
    body: Body,
    received_at: Timestamp,
    id: Uuid,
    supersedes: Option<Supersedes>,
) -> Result<Assessed, Problem> {
    let (submission, content_type) = (body.bytes.clone(), body.content_type.clone());
    let size = body.bytes.len();
    let sub = state.compute_for(size, move || read(&body)).await??;
    let root = Loc::Root;
    let sensor_id = sub.sensor_id.clone().ok_or_else(|| {
        Problem::validation(Invalid::one(
            root.key("sensor_id"),
            "is required to store a triad (POST /v1/identify/triad computes one without)",
        ))
    })?;
    let station_id = station(principal, sub.station_id.as_deref())?;
    let performed_at = match sub.performed_at {
        None => received_at,
        Some(t) => performed_when(t, received_at)
            .map_err(|why| Problem::validation(Invalid::one(root.key("performed_at"), why)))?,
    };
    let sensor_type = sensor_type(
        state,
        principal,
        &sensor_id,
        sub.sensor_type.as_ref(),
        true,
        received_at,
    )
    .await?;
    if let Some(t) = &sensor_type
        && let Some(unit) = t.unit.as_ref().filter(|u| **u != sub.unit)
    {
        return Err(Problem::validation(Invalid::one(
            root.key("unit"),
            format!(
                "is `{}`, but sensor type `{}` sets its limits in `{unit}`: send the outputs in \
                 `{unit}`, or give the sensor a type in `{}`",
                echo(&sub.unit),
                t.type_id,
                echo(&sub.unit)
            ),
        )));
    }
    let assigns_type = sub.sensor_type.is_some();
    let mut sub = sub;
    let (used, held_by) = if sub.standards.is_empty() {
        (Vec::new(), Vec::new())
    } else {
        let roles: Vec<(&str, Option<String>)> = sub
            .standards
            .iter()
            .map(|(role, id)| (*role, Some(id.clone())))
            .collect();
        let r = resolve(state, &roles, performed_at).await?;
        sub.stand = r.stand.core();
        (r.used, r.held_by)
    };
    let uses = Resolved::uses(&used);
    let runs = match &sub.form {
        Form::Known { runs, .. } => runs.len(),
        _ => 1,
    };
    let judged_by = sensor_type.clone();
    let previous = state
        .store
        .previous_calibration(sensor_id.clone(), performed_at, state.web.basis)
        .await?;
    let result = state
        .compute_for(size, move || -> Result<TriadResult, Problem> {
            let mut sub = sub;
            if let Some(t) = &judged_by {
                sub.coverage = t.coverage();
            }
            let mut result = compute(sub)?;
            if let Some(t) = &judged_by {
                judge(&mut result, t)?;
            }
            if let Some(p) = &previous {
                found(&mut result, p);
            }
            result.standards = used;
            result.held_by = held_by;
            Ok(result)
        })
        .await??;
    let due_at = sensor_type
        .as_ref()
        .filter(|_| result.decision.is_some())
        .map(|t| performed_at.plus_seconds(i64::from(t.interval_days) * 86_400));
    let record = NewCalibration {
        id,
        sensor_id: sensor_id.clone(),
        station_id: station_id.clone(),
        performed_at,
        received_at,
        unit: result.unit.clone(),
        model: Model::new(
            [Term::K0, Term::Ki, Term::Kp, Term::Ko]
                .into_iter()
                .chain(result.s2.map(|_| Term::Kii))
                .collect(),
        )
        .map_err(|_| Problem::internal())?,
        runs,
        coefficients: TermMap(Vec::new()),
        std_errors: TermMap(Vec::new()),
        result: Bytes::new(),
        submission,
        content_type,
        submitted_by: principal.id.clone(),
        sensor_type: sensor_type.map(|t| t.type_id),
        assigns_type,
        verdict: result.decision.as_ref().map(|d| d.verdict),
        due_at,
        expanded: None,
        triad: Some(elements(&result)),
        standards: uses,
    };
    let view = StoredTriad {
        id,
        station_id,
        performed_at,
        received_at,
        supersedes,
        due_at,
        result,
    };
    let result = Bytes::from(serde_json::to_vec(&view).map_err(|err| {
        tracing::error!(error = %err, "a triad's result did not serialise");
        Problem::internal()
    })?);
    Ok(Assessed {
        sensor_id,
        result: result.clone(),
        record: Some(NewCalibration { result, ..record }),
    })
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
            s2: t.s2,
            source,
        },
        format,
    )
}
