//! Sensors: listing, history, coefficients for control systems, compensation.

use accelcal_core::{Compensator, TermMap};
use axum::Json;
use axum::extract::{Path, RawQuery, State};
use serde::Serialize;
use serde_json::value::RawValue;
use uuid::Uuid;

use super::AppState;
use super::extract::{Body, Params};
use super::page::Page;
use super::problem::Problem;
use crate::auth::{Principal, Role};
use crate::input::check::{Chars, check_str, optional};
use crate::input::{Checker, FieldError, Ptr};
use crate::store::{CalibrationSummary, HistoryQuery, SensorSummary};
use crate::submission::{MAX_ID_CHARS, MAX_READING};
use crate::timestamp::Timestamp;

/// Most outputs compensated in one request.
pub const MAX_OUTPUTS: usize = 10_000;
/// Largest magnitude of a known `a_p` or `a_o`, in g.
pub const MAX_CROSS_G: f64 = 100.0;

fn unknown_sensor(sensor_id: &str) -> Problem {
    Problem::not_found(format!("no sensor `{sensor_id}` has been calibrated"))
}

/// Looks a sensor up; ids that cannot be valid are simply not found.
async fn sensor(state: &AppState, sensor_id: &str) -> Result<SensorSummary, Problem> {
    if check_str(sensor_id, MAX_ID_CHARS, Chars::Identifier).is_err() {
        return Err(unknown_sensor(sensor_id));
    }
    state
        .store
        .sensor(sensor_id.to_owned())
        .await?
        .ok_or_else(|| unknown_sensor(sensor_id))
}

/// `GET /v1/sensors`: sensors in id order, keyset-paginated.
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
    RawQuery(query): RawQuery,
) -> Result<Json<Page<SensorSummary>>, Problem> {
    principal.require(Role::Reader)?;
    let params = Params::parse(query.as_deref(), &["limit", "after"])?;
    let limit = params.limit()?;
    let after = params
        .get("after")
        .map(|a| {
            check_str(a, MAX_ID_CHARS, Chars::Identifier)
                .map(|()| a.to_owned())
                .map_err(|e| Problem::bad_parameter("after", format!("is not a sensor id: it {e}")))
        })
        .transpose()?;
    let items = state.store.sensors(after, limit + 1).await?;
    Ok(Json(Page::from_overfetch(items, limit, |s| {
        s.sensor_id.clone()
    })))
}

/// `GET /v1/sensors/{sensor_id}`.
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
) -> Result<Json<SensorSummary>, Problem> {
    principal.require(Role::Reader)?;
    Ok(Json(sensor(&state, &sensor_id).await?))
}

fn time_param(params: &Params, name: &str) -> Result<Option<Timestamp>, Problem> {
    params
        .get(name)
        .map(|s| Timestamp::parse(s).map_err(|e| Problem::bad_parameter(name, e)))
        .transpose()
}

/// `GET /v1/sensors/{sensor_id}/calibrations`: newest `performed_at` first,
/// optionally within `from`..=`to` (an empty range gives an empty page),
/// keyset-paginated by calibration id.
pub async fn history(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    RawQuery(query): RawQuery,
) -> Result<Json<Page<CalibrationSummary>>, Problem> {
    principal.require(Role::Reader)?;
    let params = Params::parse(query.as_deref(), &["from", "to", "limit", "after"])?;
    let limit = params.limit()?;
    let (from, to) = (time_param(&params, "from")?, time_param(&params, "to")?);
    let before = params
        .get("after")
        .map(|a| {
            Uuid::try_parse(a)
                .map_err(|_| Problem::bad_parameter("after", "must be a calibration id (UUID)"))
        })
        .transpose()?;
    sensor(&state, &sensor_id).await?;
    if let Some(id) = before {
        let known = state.store.calibration_summary(id).await?;
        if known.is_none_or(|c| c.sensor_id != sensor_id) {
            return Err(Problem::not_found(format!(
                "sensor `{sensor_id}` has no calibration `{id}` to continue after"
            )));
        }
    }
    let q = HistoryQuery {
        from,
        to,
        before,
        limit: limit + 1,
    };
    let items = state.store.history(sensor_id, q).await?;
    Ok(Json(Page::from_overfetch(items, limit, |c| {
        c.id.to_string()
    })))
}

/// What a control system loads: the fused coefficients of one calibration.
#[derive(Debug, Serialize)]
pub struct Coefficients {
    sensor_id: String,
    calibration_id: Uuid,
    performed_at: String,
    unit: String,
    model: Box<RawValue>,
    coefficients: Box<RawValue>,
    std_errors: Box<RawValue>,
}

impl From<CalibrationSummary> for Coefficients {
    fn from(c: CalibrationSummary) -> Self {
        Coefficients {
            sensor_id: c.sensor_id,
            calibration_id: c.id,
            performed_at: c.performed_at,
            unit: c.unit,
            model: c.model,
            coefficients: c.coefficients,
            std_errors: c.std_errors,
        }
    }
}

/// `GET /v1/sensors/{sensor_id}/coefficients`: the latest calibration's fused values.
pub async fn coefficients(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
) -> Result<Json<Coefficients>, Problem> {
    principal.require(Role::Reader)?;
    Ok(Json(sensor(&state, &sensor_id).await?.latest.into()))
}

/// The answer of a compensation.
#[derive(Debug, Serialize)]
pub struct Compensated {
    sensor_id: String,
    calibration_id: Uuid,
    unit: String,
    a_i: Vec<f64>,
}

/// `POST /v1/sensors/{sensor_id}/compensate`: input accelerations (g) from
/// raw outputs, with the latest calibration or the one named.
pub async fn compensate(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    body: Body,
) -> Result<Json<Compensated>, Problem> {
    principal.require(Role::Reader)?;
    let value = body.json()?;
    let root = Ptr::root();
    let mut c = Checker::new();
    let Some(map) = c.object(&value, &root, &["outputs", "a_p", "a_o", "calibration_id"]) else {
        return Err(c.finish().unwrap_err().into());
    };
    let numbers =
        |c: &mut Checker, key: &str, bound: f64, len: Option<usize>| -> Option<Vec<f64>> {
            let v = optional(map, key)?;
            let p = root.key(key);
            let items = c.array(v, &p, 1, MAX_OUTPUTS)?;
            if let Some(n) = len.filter(|n| *n != items.len()) {
                c.error(
                    &p,
                    format!("must hold one value per output ({n}), not {}", items.len()),
                );
                return None;
            }
            let xs: Vec<f64> = items
                .iter()
                .enumerate()
                .filter_map(|(k, x)| c.number(x, &p.index(k), bound))
                .collect();
            (xs.len() == items.len()).then_some(xs)
        };
    if optional(map, "outputs").is_none() {
        c.error(&root.key("outputs"), "is required");
    }
    let outputs = numbers(&mut c, "outputs", MAX_READING, None);
    let n = outputs.as_ref().map(Vec::len);
    let a_p = numbers(&mut c, "a_p", MAX_CROSS_G, n);
    let a_o = numbers(&mut c, "a_o", MAX_CROSS_G, n);
    let calibration_id = optional(map, "calibration_id").and_then(|v| {
        let p = root.key("calibration_id");
        match v.as_str().map(Uuid::try_parse) {
            Some(Ok(id)) => Some(id),
            _ => {
                c.error(&p, "must be a calibration id (UUID)");
                None
            }
        }
    });
    c.finish()?;
    let outputs = outputs.expect("checked");

    let summary = match calibration_id {
        None => sensor(&state, &sensor_id).await?.latest,
        Some(id) => state
            .store
            .calibration_summary(id)
            .await?
            .filter(|s| s.sensor_id == sensor_id)
            .ok_or_else(|| {
                Problem::not_found(format!("sensor `{sensor_id}` has no calibration `{id}`"))
            })?,
    };
    let coefficients: TermMap<f64> =
        serde_json::from_str(summary.coefficients.get()).map_err(|e| {
            crate::store::StoreError::Corrupt(format!("coefficients of {}: {e}", summary.id))
        })?;
    let comp = Compensator::new(&coefficients).map_err(|e| {
        Problem::validation(vec![FieldError {
            pointer: root.key("calibration_id").to_string(),
            detail: format!("calibration {} cannot be used: {e}", summary.id),
        }])
    })?;
    let mut errors = Vec::new();
    let a_i: Vec<f64> = outputs
        .iter()
        .enumerate()
        .map(|(k, u)| {
            let ap = a_p.as_ref().map_or(0.0, |v| v[k]);
            let ao = a_o.as_ref().map_or(0.0, |v| v[k]);
            comp.input(*u, ap, ao).unwrap_or_else(|e| {
                errors.push(FieldError {
                    pointer: root.key("outputs").index(k).to_string(),
                    detail: e.to_string(),
                });
                f64::NAN
            })
        })
        .collect();
    if !errors.is_empty() {
        return Err(Problem::validation(errors));
    }
    Ok(Json(Compensated {
        sensor_id,
        calibration_id: summary.id,
        unit: summary.unit,
        a_i,
    }))
}
