//! Computations that store nothing: `POST /v1/identify` and `POST /v1/fuse`.

use accelcal_core::{Error as CoreError, Estimates, FusionError, Term, TermMap, estimate};
use axum::Json;
use axum::extract::State;
use axum::response::{IntoResponse, Response};
use serde_json::Value;

use super::extract::Body;
use super::problem::Problem;
use super::{AppState, evaluate};
use crate::auth::{Principal, Role};
use crate::input::check::optional;
use crate::input::{Checker, FieldError, Ptr};
use crate::submission::{MAX_BATCHES, MAX_READING, MAX_RUNS, ResultView};
use crate::timestamp::Timestamp;

/// `POST /v1/identify`: a submission computed and returned, not stored.
pub async fn identify(
    State(_): State<AppState>,
    principal: Principal,
    body: Body,
) -> Result<Response, Problem> {
    principal.require(Role::Reader)?;
    let value = body.submission()?;
    let now = Timestamp::now();
    let evaluated = evaluate(value, now).await?;
    let station = principal
        .station_id
        .as_deref()
        .or(evaluated.submission.station_id.as_deref());
    Ok(Json(ResultView::new(&evaluated, None, station, now)).into_response())
}

fn fuse_request(value: &Value) -> Result<(TermMap<Vec<f64>>, usize), Vec<FieldError>> {
    let root = Ptr::root();
    let mut c = Checker::new();
    let Some(map) = c.object(value, &root, &["values", "batches"]) else {
        return Err(c.finish().unwrap_err());
    };
    let batches = match optional(map, "batches") {
        Some(v) => c.integer(v, &root.key("batches"), 1, MAX_BATCHES),
        None => Some(2),
    };
    let mut values = Vec::new();
    if let Some(v) = c.required(map, &root, "values") {
        let p = root.key("values");
        match v.as_object() {
            None => c.error(
                &p,
                "must be an object keyed by term name, e.g. {\"k0\": [...]}",
            ),
            Some(m) if m.is_empty() => c.error(&p, "must name at least one term"),
            Some(m) => {
                for (name, xs) in m {
                    let tp = p.key(name);
                    let term = match name.parse::<Term>() {
                        Ok(t) => Some(t),
                        Err(e) => {
                            c.error(&tp, e.to_string());
                            None
                        }
                    };
                    let Some(items) = c.array(xs, &tp, 2, MAX_RUNS) else {
                        continue;
                    };
                    let nums: Vec<f64> = items
                        .iter()
                        .enumerate()
                        .filter_map(|(k, x)| c.number(x, &tp.index(k), MAX_READING))
                        .collect();
                    if let Some(t) = term
                        && nums.len() == items.len()
                    {
                        values.push((t, nums));
                    }
                }
            }
        }
    }
    c.finish()?;
    // Model order, whatever order the object had.
    values.sort_by_key(|(t, _)| *t);
    Ok((TermMap(values), batches.expect("checked") as usize))
}

fn fuse_error(e: &CoreError, batches_given: bool) -> FieldError {
    let values = Ptr::root().key("values");
    let pointer = match e {
        CoreError::ValueCount { term, .. } => values.key(term.name()),
        CoreError::Fusion {
            source: FusionError::TooFewRuns { .. } | FusionError::NoBatches,
            ..
        } if batches_given => Ptr::root().key("batches"),
        CoreError::Fusion { term, .. } => values.key(term.name()),
        _ => values,
    };
    FieldError {
        pointer: pointer.to_string(),
        detail: e.to_string(),
    }
}

/// `POST /v1/fuse`: mean and batch-estimation fusion of given per-run values
/// (how the paper's Table 2 is reproduced).
pub async fn fuse(
    State(_): State<AppState>,
    principal: Principal,
    body: Body,
) -> Result<Json<Estimates>, Problem> {
    principal.require(Role::Reader)?;
    let value = body.json()?;
    let (values, batches) = fuse_request(&value)?;
    let batches_given = value.get("batches").is_some_and(|b| !b.is_null());
    estimate(&values, batches)
        .map(Json)
        .map_err(|e| Problem::validation(vec![fuse_error(&e, batches_given)]))
}
