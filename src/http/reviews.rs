//! Review of stored calibrations (issue 28): approve or reject, withdraw,
//! amend, supersede, reprocess, and the signatures that record each act —
//! each act in the application layer ([`crate::app::review`],
//! [`crate::app::supersede`]): a refusal for the signer's role or their own
//! work is a 403, one for the calibration's state (approving a withdrawn
//! one, withdrawing twice) a 409 naming the state.

use axum::Json;
use axum::extract::{Path, State};
use axum::http::HeaderMap;
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};
use uuid::Uuid;

use super::AppState;
use super::auth::require;
use super::body::Body;
use super::path_id;
use super::problem::Problem;
use super::query::Params;
use super::stored::created;
use super::ui::issue::issuing;
use crate::app::review::{self, Reviewed};
use crate::app::supersede::{self, Reprocessed};
use crate::domain::auth::{Principal, Role};
use crate::domain::review::{
    ReviewBody, Signature, State as ReviewState, WithdrawBody, check_reason,
};
use crate::domain::timestamp::Timestamp;

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
    Problem::from(review::unknown(id))
}

/// `POST /v1/calibrations/{id}/review`: approve or reject.
#[utoipa::path(
    post,
    path = "/v1/calibrations/{id}/review",
    tag = "review",
    operation_id = "reviewCalibration",
    summary = "Approve or reject a submitted calibration (reviewer or admin).",
    description = "Signs the decision with the token's holder, role and id. The \
        reviewer may not be who submitted the calibration, or a calibration it \
        replaces (the same holder, or the same token when it names none): 403. Only a \
        `submitted` calibration can be approved or rejected, or an `under_review` one \
        approved: 409 otherwise. A rejection needs a comment; approving a held \
        (`under_review`) calibration releases the hold and needs the disposition in the \
        comment (422 at `/comment` without).",
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
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Body,
) -> Result<Json<Reviewed>, Problem> {
    require(&principal, Role::Reviewer)?;
    let id = path_id(&id, "calibration")?;
    let act = body
        .json::<ReviewBody>()?
        .act(principal, Timestamp::now())?;
    let issuing = issuing(&state, &headers, id, &act).await;
    Ok(Json(review::record(&state.lab, id, act, issuing).await?))
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
    Ok(Json(review::record(&state.lab, id, act, None).await?))
}

/// The body of `POST /v1/calibrations/{id}/amend`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AmendBody {
    /// Why the issued certificate is amended (printed on the amendment);
    /// 1–2 000 characters.
    #[schema(schema_with = crate::domain::schema::reason)]
    pub reason: String,
}

/// `POST /v1/calibrations/{id}/amend`.
#[utoipa::path(
    post,
    path = "/v1/calibrations/{id}/amend",
    tag = "review",
    operation_id = "amendCertificate",
    summary = "Amend an issued certificate: its next revision, with today's facts (reviewer or admin).",
    description = "An issued certificate never changes; what it says changes by an amendment. \
        The next revision of the same certificate number is rendered from the current item, \
        customer and laboratory, marked \"Amendment n to certificate No. …\" with the reason (the \
        DCC's `reportAmendedSubstituted`, `amended`), stored, and answered from then on; every \
        revision stays retrievable (`GET …/certificate?revision=N`). The amendment's SHA-256s \
        are in the audit trail. Only an approved calibration's certificate is amended (409 \
        otherwise).",
    params(super::openapi::CalibrationIdPath),
    request_body(content((AmendBody = "application/json",
        example = json!({"reason": "The customer's address was corrected."})))),
    responses(
        (status = 201, description = "The new revision.", body = crate::store::Revision,
            headers(("Location" = String, description = "The new revision's certificate."))),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::StateConflict),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn amend(
    State(state): State<AppState>,
    principal: Principal,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Reviewer)?;
    let id = path_id(&id, "calibration")?;
    let reason = check_reason(Some(&body.json::<AmendBody>()?.reason))
        .map_err(|why| Problem::validation(crate::domain::field::Invalid::one("/reason", why)))?;
    let c = super::ui::issue::amend(
        &state,
        &headers,
        &id.to_string(),
        reason,
        crate::domain::audit::Actor::from(&principal),
    )
    .await?;
    tracing::info!(calibration = %id, revision = c.revision, by = %principal.id, "certificate amended");
    let location = format!("/v1/calibrations/{id}/certificate?revision={}", c.revision);
    Ok((
        axum::http::StatusCode::CREATED,
        [(axum::http::header::LOCATION, location)],
        Json(crate::store::Revision::from(&c)),
    )
        .into_response())
}

/// The query of `POST /v1/calibrations/{id}/supersede` (its pattern is
/// [`crate::domain::schema::SAID`], written out because the derive takes a
/// literal; a test holds them equal).
#[derive(Debug, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct SupersedeQuery {
    /// Why the calibration is superseded (printed on both certificates);
    /// 1–2 000 characters.
    #[param(
        min_length = 1,
        max_length = 2000,
        pattern = r"^[^\u0000-\u0008\u000B\u000C\u000E-\u001F\u007F-\u009F]*[^\s\u0000-\u001F\u007F-\u009F][^\u0000-\u0008\u000B\u000C\u000E-\u001F\u007F-\u009F]*$"
    )]
    reason: String,
}

/// `POST /v1/calibrations/{id}/supersede`: a corrected submission replaces
/// a calibration.
#[utoipa::path(
    post,
    path = "/v1/calibrations/{id}/supersede",
    tag = "review",
    operation_id = "supersedeCalibration",
    summary = "Replace a calibration by a corrected submission.",
    description = "The body is a submission of the calibration's kind, as for \
        `POST /v1/calibrations` or, for a triad's, `POST /v1/calibrations/triad` (JSON or \
        CSV, of any sensor of that kind: a wrong sensor id is corrected so). It is computed and \
        stored as a new calibration that records what it `supersedes` and why, while \
        the old one becomes `superseded` (it stays, marked, and stops counting) — both \
        in one transaction, or neither. A reviewer or admin may supersede any \
        `submitted` or `approved` calibration; the station token that submitted one \
        may supersede it itself within 24 h of its submission. A calibration is \
        superseded once (409 afterwards, as for a `rejected` or `withdrawn` one).",
    params(super::openapi::CalibrationIdPath, SupersedeQuery),
    request_body(content(
        (super::openapi::CorrectionSchema = "application/json"),
        (super::openapi::RawBodySchema = "text/csv"),
    )),
    responses(
        (status = 201, description = "The corrected calibration, stored; the old one superseded.",
            body = super::openapi::StoredResultSchema,
            headers(("Location" = String, description = "The new calibration's URL."))),
        (status = 400, response = super::openapi::BadRequest),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::StateConflict),
        (status = 413, response = super::openapi::TooLarge),
        super::openapi::Always,
        super::openapi::BodyProblems,
    )
)]
pub async fn supersede(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
    Params(query): Params<SupersedeQuery>,
    body: Body,
) -> Result<Response, Problem> {
    require(&principal, Role::Station)?;
    let old = path_id(&id, "calibration")?;
    let reason =
        check_reason(Some(&query.reason)).map_err(|why| Problem::bad_parameter("reason", why))?;
    let upload = body;
    let submitted = supersede::supersede(&state.lab, principal, old, reason, upload).await?;
    Ok(created(submitted))
}

/// `POST /v1/calibrations/{id}/reprocess`.
#[utoipa::path(
    post,
    path = "/v1/calibrations/{id}/reprocess",
    tag = "review",
    operation_id = "reprocessCalibration",
    summary = "Compute a stored submission again with the current method (reviewer or admin).",
    description = "The stored submission is evaluated again as it was received (same \
        body, same reception time) with this accelcal's method. When every number — \
        model, unit, runs, each fused coefficient, standard error and expanded \
        uncertainty (a triad's: its method and every element of b, S, T and S2 with \
        theirs), bit for bit — is the same, a `confirm` signature records it \
        and the state is kept; otherwise a new calibration supersedes it, with the \
        reason \"reprocessed with accelcal … (core …)\" and what changed. Only a \
        `submitted` or `approved` calibration is reprocessed (409 otherwise). The \
        sensor's type and the standards are today's: a submission they now refuse \
        (a type in another unit, a standard removed) is a 422 saying why, and \
        nothing is recorded.",
    params(super::openapi::CalibrationIdPath),
    responses(
        (status = 200, description = "Confirmed, or superseded (`replacement_id`).", body = Reprocessed),
        (status = 403, response = super::openapi::Forbidden),
        (status = 404, response = super::openapi::NotFound),
        (status = 409, response = super::openapi::StateConflict),
        (status = 422, response = super::openapi::Invalid),
        super::openapi::Always,
    )
)]
pub async fn reprocess(
    State(state): State<AppState>,
    principal: Principal,
    Path(id): Path<String>,
) -> Result<Json<Reprocessed>, Problem> {
    require(&principal, Role::Reviewer)?;
    let id = path_id(&id, "calibration")?;
    Ok(Json(supersede::reprocess(&state.lab, principal, id).await?))
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

#[cfg(test)]
mod tests {
    use utoipa::IntoParams;

    use super::*;

    #[test]
    fn the_reason_parameter_is_the_schema_of_a_reason() {
        let params = SupersedeQuery::into_params(|| None);
        let reason = params.iter().find(|p| p.name == "reason").unwrap();
        assert!(matches!(reason.required, utoipa::openapi::Required::True));
        let schema = serde_json::to_value(&reason.schema).unwrap();
        assert_eq!(schema["pattern"], crate::domain::schema::SAID);
    }
}
