//! Sensors: listing (by status), one sensor, assigning its type, history,
//! stability ([`super::stability`]).

use axum::Json;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use serde::Deserialize;
use utoipa::{IntoParams, ToSchema};
use uuid::Uuid;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::lookup::{SensorListQuery, sensor, unknown_sensor};
use super::page::Page;
use super::problem::{Kind, Problem};
use super::query::{Params, instant, limit};
use super::rendered::APPLICATION_JSON;
use super::stability::{Stability, StabilityParams, report_of};
use crate::app::definitions;
use crate::domain::auth::{Principal, Role};
use crate::store::{HistoryQuery, SensorSummary};

/// `GET /v1/sensors`: sensors in id order, keyset-paginated.
#[utoipa::path(
    get,
    path = "/v1/sensors",
    tag = "sensors",
    operation_id = "listSensors",
    summary = "Sensors in id order with calibration count and latest fused coefficients.",
    params(SensorListQuery),
    responses(
        (status = 200, description = "One page.", body = super::openapi::SensorPageSchema),
        (status = 400, response = super::openapi::BadRequest),
        super::openapi::Always,
    )
)]
pub async fn list(
    State(state): State<AppState>,
    principal: Principal,
    Params(q): Params<SensorListQuery>,
) -> Result<Json<Page<SensorSummary>>, Problem> {
    require(&principal, Role::Reader)?;
    let (query, limit) = q.store_query()?;
    let items = state.store.sensors(query).await?;
    Ok(Json(Page::from_overfetch(items, limit, |s| {
        s.sensor_id.clone()
    })))
}

/// `GET /v1/sensors/{sensor_id}`.
#[utoipa::path(
    get,
    path = "/v1/sensors/{sensor_id}",
    tag = "sensors",
    operation_id = "getSensor",
    summary = "One sensor.",
    params(super::openapi::SensorIdPath),
    responses(
        (status = 200, description = "The sensor.", body = SensorSummary),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn get(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
) -> Result<Json<SensorSummary>, Problem> {
    require(&principal, Role::Reader)?;
    Ok(Json(sensor(&state, &sensor_id).await?))
}

/// The query of `GET /v1/sensors/{sensor_id}/calibrations`.
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct HistoryParams {
    /// Only calibrations performed at or after this instant (RFC 3339).
    #[param(value_type = Option<String>, format = DateTime)]
    from: Option<String>,
    /// Only calibrations performed at or before this instant (RFC 3339);
    /// `from` after `to` gives an empty page.
    #[param(value_type = Option<String>, format = DateTime)]
    to: Option<String>,
    /// Page size.
    #[param(value_type = Option<u32>, minimum = 1, maximum = 500, default = 50)]
    limit: Option<String>,
    /// The `next` cursor of the previous page (the last calibration id it
    /// held); 404 when it is not a calibration of this sensor.
    #[param(value_type = Option<String>, format = Uuid)]
    after: Option<String>,
}

/// `GET /v1/sensors/{sensor_id}/calibrations`: newest `performed_at` first,
/// optionally within `from`..=`to` (an empty range gives an empty page),
/// keyset-paginated by calibration id.
#[utoipa::path(
    get,
    path = "/v1/sensors/{sensor_id}/calibrations",
    tag = "sensors",
    operation_id = "listSensorCalibrations",
    summary = "A sensor's calibrations, newest performed_at first.",
    params(super::openapi::SensorIdPath, HistoryParams),
    responses(
        (status = 200, description = "One page.", body = super::openapi::CalibrationPageSchema),
        (status = 400, response = super::openapi::BadRequest),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn history(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    Params(q): Params<HistoryParams>,
) -> Result<Response, Problem> {
    require(&principal, Role::Reader)?;
    let limit = limit(q.limit.as_deref())?;
    let (from, to) = (
        instant("from", q.from.as_deref())?,
        instant("to", q.to.as_deref())?,
    );
    let before = q
        .after
        .map(|a| {
            Uuid::try_parse(&a)
                .map_err(|_| Problem::bad_parameter("after", "must be a calibration id (UUID)"))
        })
        .transpose()?;
    match sensor(&state, &sensor_id).await {
        Ok(_) => {}
        // A sensor none of whose calibrations is in use any more (all
        // rejected or withdrawn) still has its history.
        Err(p) if p.kind == Kind::NotFound => {
            let any = HistoryQuery {
                from: None,
                to: None,
                before: None,
                limit: 1,
            };
            if state
                .store
                .history_ids(sensor_id.clone(), any)
                .await?
                .is_empty()
            {
                return Err(p);
            }
        }
        Err(p) => return Err(p),
    }
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
    // The page's ids, then each summary as rendered before; the summaries
    // are read (and rendered, and kept) only when one is not kept yet.
    let ids = state
        .store
        .history_ids(sensor_id.clone(), q.clone())
        .await?;
    let kept: Option<Vec<Bytes>> = ids.iter().map(|id| state.summaries.get(id)).collect();
    let items = match kept {
        Some(bodies) => ids.into_iter().map(|(id, _)| id).zip(bodies).collect(),
        None => {
            let mut items = Vec::new();
            for c in state.store.history(sensor_id, q).await? {
                let body = Bytes::from(serde_json::to_vec(&c).map_err(|e| {
                    tracing::error!(error = %e, "rendering a calibration summary failed");
                    Problem::internal()
                })?);
                state.summaries.insert((c.id, c.state), body.clone());
                items.push((c.id, body));
            }
            items
        }
    };
    let body = page_of_rendered(items, limit);
    Ok(([(header::CONTENT_TYPE, APPLICATION_JSON.clone())], body).into_response())
}

/// Calibration summaries kept rendered at most (each under a kilobyte).
pub const SUMMARIES: usize = 4096;

/// The JSON of a [`Page`] of calibration summaries from their renderings:
/// `{"items":[…],"next":…}` as serde writes a `Page<CalibrationSummary>`,
/// the last of `limit + 1` fetched items only telling that a next page
/// exists.
fn page_of_rendered(mut items: Vec<(Uuid, Bytes)>, limit: usize) -> Bytes {
    let next = if items.len() > limit {
        items.truncate(limit);
        items.last().map(|(id, _)| *id)
    } else {
        None
    };
    let mut out = Vec::with_capacity(32 + items.iter().map(|(_, b)| b.len() + 1).sum::<usize>());
    out.extend_from_slice(b"{\"items\":[");
    for (k, (_, body)) in items.iter().enumerate() {
        if k > 0 {
            out.push(b',');
        }
        out.extend_from_slice(body);
    }
    out.extend_from_slice(b"],\"next\":");
    match next {
        Some(id) => {
            out.push(b'"');
            out.extend_from_slice(
                id.hyphenated()
                    .encode_lower(&mut Uuid::encode_buffer())
                    .as_bytes(),
            );
            out.push(b'"');
        }
        None => out.extend_from_slice(b"null"),
    }
    out.push(b'}');
    Bytes::from(out)
}

/// The body of `PUT /v1/sensors/{sensor_id}`.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SensorUpdate {
    /// The sensor type to assign (it must exist); it applies to the
    /// sensor's next calibrations, never to stored ones.
    #[schema(value_type = crate::domain::schema::Identifier)]
    sensor_type: String,
}

/// `PUT /v1/sensors/{sensor_id}` (admin): assigns a sensor type.
#[utoipa::path(
    put,
    path = "/v1/sensors/{sensor_id}",
    tag = "sensors",
    operation_id = "updateSensor",
    summary = "Assign a sensor type (admin); it applies to the next calibrations.",
    params(super::openapi::SensorIdPath),
    request_body(content((SensorUpdate = "application/json"))),
    responses(
        (status = 200, description = "The sensor.", body = SensorSummary),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn update(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    body: Body,
) -> Result<Json<SensorSummary>, Problem> {
    require(&principal, Role::Admin)?;
    let update: SensorUpdate = body.json()?;
    sensor(&state, &sensor_id).await?;
    if !definitions::retype(&state.lab, &principal, &sensor_id, update.sensor_type).await? {
        return Err(unknown_sensor(&sensor_id));
    }
    Ok(Json(sensor(&state, &sensor_id).await?))
}

/// `GET /v1/sensors/{sensor_id}/stability`.
#[utoipa::path(
    get,
    path = "/v1/sensors/{sensor_id}/stability",
    tag = "sensors",
    operation_id = "getStability",
    summary = "Spread, drift and control chart of a sensor's fused coefficients over its history.",
    params(super::openapi::SensorIdPath, StabilityParams),
    responses(
        (status = 200, description = "The report.", body = Stability),
        (status = 400, response = super::openapi::BadRequest),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn stability(
    State(state): State<AppState>,
    principal: Principal,
    Path(sensor_id): Path<String>,
    Params(q): Params<StabilityParams>,
) -> Result<Json<Stability>, Problem> {
    require(&principal, Role::Reader)?;
    let (from, to) = (
        instant("from", q.from.as_deref())?,
        instant("to", q.to.as_deref())?,
    );
    Ok(Json(
        report_of(&state, &sensor_id, from, to).await?.stability,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::CalibrationSummary;

    /// A page built from kept renderings is, byte for byte, what serde
    /// writes for the same summaries as a `Page` — empty, short, full and
    /// overfetched.
    #[test]
    fn a_page_of_renderings_is_the_page_serde_writes() {
        let all: Vec<CalibrationSummary> = (1..=4)
            .map(|i| CalibrationSummary::for_test(i, "S", 1e-3 * i as f64, -1.2))
            .collect();
        for (n, limit) in [(0, 3), (2, 3), (3, 3), (4, 3), (2, 1)] {
            let items = all[..n].to_vec();
            let rendered = items
                .iter()
                .map(|c| (c.id, Bytes::from(serde_json::to_vec(c).unwrap())))
                .collect();
            let expected =
                serde_json::to_vec(&Page::from_overfetch(items, limit, |c| c.id.to_string()))
                    .unwrap();
            assert_eq!(
                page_of_rendered(rendered, limit),
                Bytes::from(expected),
                "{n} items, limit {limit}"
            );
        }
    }
}
