//! Review of stored calibrations (issue 28): approve or reject, withdraw,
//! and the signatures that record each act.
//!
//! Each act is checked by the domain ([`crate::domain::review::Act::check`])
//! inside the store's transaction that records it: a refusal for the
//! signer's role or their own work is a 403, one for the calibration's
//! state (approving a withdrawn one, withdrawing twice) a 409 naming the
//! state.

use axum::Json;
use axum::extract::{Path, State};
use serde::Serialize;
use utoipa::ToSchema;
use uuid::Uuid;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::path_id;
use super::problem::{Kind, Problem};
use crate::domain::auth::{Principal, Role};
use crate::domain::review::{Act, ReviewBody, Signature, State as ReviewState, WithdrawBody};
use crate::domain::timestamp::Timestamp;
use crate::store::Signed;

/// What an act came to: the calibration's new state and the signature.
#[derive(Debug, Serialize, ToSchema)]
pub struct Reviewed {
    /// The calibration.
    calibration_id: Uuid,
    /// Its state now.
    state: ReviewState,
    /// The signature just recorded.
    signature: Signature,
}

/// A calibration's review record.
#[derive(Debug, Serialize, ToSchema)]
pub struct Signatures {
    /// The calibration.
    calibration_id: Uuid,
    /// Its state: `submitted` until a signature changes it.
    state: ReviewState,
    /// Every signature, in order.
    signatures: Vec<Signature>,
}

fn unknown(id: Uuid) -> Problem {
    Problem::not_found(format!("no calibration with id `{id}`"))
}

/// Records `act` on calibration `id`, answering its outcome (also for the
/// pages' review form).
pub(crate) async fn record(state: &AppState, id: Uuid, act: Act) -> Result<Reviewed, Problem> {
    let action = act.action;
    match state.store.sign(id, act).await? {
        Signed::Done(signature, sensor_id) => {
            metrics::counter!("accelcal_reviews_total", "action" => action.as_str()).increment(1);
            tracing::info!(
                calibration = %id, sensor = %sensor_id, action = action.as_str(),
                by = %signature.token_id, "calibration signed"
            );
            Ok(Reviewed {
                calibration_id: id,
                state: signature.state,
                signature,
            })
        }
        Signed::NotFound => Err(unknown(id)),
        Signed::Refused(why) if why.is_permission() => Err(Problem::forbidden(why.to_string())),
        Signed::Refused(why) => Err(Problem::new(Kind::StateConflict, why.to_string())),
    }
}

/// `POST /v1/calibrations/{id}/review`: approve or reject.
#[utoipa::path(
    post,
    path = "/v1/calibrations/{id}/review",
    tag = "review",
    operation_id = "reviewCalibration",
    summary = "Approve or reject a submitted calibration (reviewer or admin).",
    description = "Signs the decision with the token's holder, role and id. The \
        reviewer may not be who submitted the calibration (the same holder, or \
        the same token when it names none): 403. Only a `submitted` calibration \
        can be approved or rejected: 409 otherwise. A rejection needs a comment.",
    params(super::openapi::CalibrationIdPath),
    request_body(content((ReviewBody = "application/json",
        example = json!({"decision": "approve", "comment": "Residuals and budget checked."})))),
    responses(
        (status = 200, description = "Signed: the new state and the signature.", body = Reviewed),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::StateConflict),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn review(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
    body: Body,
) -> Result<Json<Reviewed>, Problem> {
    require(&principal, Role::Reviewer)?;
    let id = path_id(&id, "calibration")?;
    let act = body
        .json::<ReviewBody>()?
        .act(principal, Timestamp::now())?;
    record(&state, id, act).await.map(Json)
}

/// `POST /v1/calibrations/{id}/withdraw`.
#[utoipa::path(
    post,
    path = "/v1/calibrations/{id}/withdraw",
    tag = "review",
    operation_id = "withdrawCalibration",
    summary = "Withdraw a calibration, with a reason (reviewer or admin).",
    description = "The record stays, marked withdrawn with who, when and why; it is \
        no longer anyone's latest, as-found baseline or stability point, and its \
        certificate says WITHDRAWN. A `submitted` or `approved` calibration can be \
        withdrawn, once: 409 otherwise.",
    params(super::openapi::CalibrationIdPath),
    request_body(content((WithdrawBody = "application/json",
        example = json!({"reason": "Submitted under the wrong sensor id."})))),
    responses(
        (status = 200, description = "Withdrawn: the new state and the signature.", body = Reviewed),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::StateConflict),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn withdraw(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
    body: Body,
) -> Result<Json<Reviewed>, Problem> {
    require(&principal, Role::Reviewer)?;
    let id = path_id(&id, "calibration")?;
    let act = body
        .json::<WithdrawBody>()?
        .act(principal, Timestamp::now())?;
    record(&state, id, act).await.map(Json)
}

/// `GET /v1/calibrations/{id}/signatures`.
#[utoipa::path(
    get,
    path = "/v1/calibrations/{id}/signatures",
    tag = "review",
    operation_id = "getSignatures",
    summary = "A calibration's state and signatures.",
    params(super::openapi::CalibrationIdPath),
    responses(
        (status = 200, description = "Its state and every signature, in order.", body = Signatures),
        (status = 404, response = super::openapi::NotFound),
        super::openapi::Always,
    )
)]
pub async fn signatures(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Json<Signatures>, Problem> {
    require(&principal, Role::Reader)?;
    let id = path_id(&id, "calibration")?;
    let summary = state
        .store
        .calibration_summary(id)
        .await?
        .ok_or_else(|| unknown(id))?;
    let signatures = state.store.signatures(id).await?;
    Ok(Json(Signatures {
        calibration_id: id,
        state: summary.state,
        signatures,
    }))
}
