//! `POST /ui/calibrations/{id}/review`: the review form signed (issue 28).
//!
//! Signing is an act, not a side effect of being signed in: the form asks
//! for the token again, and it must be the token the session was opened
//! with. The form also carries the session's CSRF token and is refused when
//! the browser says it came from another site. The act is the API's
//! ([`crate::app::review::record`]), with the same bodies and checks.

use axum::extract::{Extension, Path, State};
use axum::http::HeaderMap;
use axum::response::{IntoResponse, Redirect, Response};
use bytes::Bytes;
use serde::Deserialize;

use super::UiError;
use super::issue::issuing;
use super::viewer::{Viewer, cross_site};
use crate::app::review;
use crate::domain::review::{Act, Action, Decision, ReviewBody, WithdrawBody};
use crate::domain::session::same_secret;
use crate::domain::timestamp::Timestamp;
use crate::http::auth::{ClientAddr, authenticate};
use crate::http::problem::Problem;
use crate::http::{AppState, path_id};

#[derive(Debug, Default, Deserialize)]
struct SignForm {
    #[serde(default)]
    act: String,
    #[serde(default)]
    comment: String,
    #[serde(default)]
    token: String,
    #[serde(default)]
    csrf: String,
}

/// `POST /ui/calibrations/{id}/review`: signs the act the form asks for,
/// with the token typed again (it must be the session's), then back to the
/// page.
pub async fn sign(
    State(state): State<AppState>,
    viewer: Viewer,
    client: Option<Extension<ClientAddr>>,
    headers: HeaderMap,
    Path(raw): Path<String>,
    body: Bytes,
) -> Result<Response, UiError> {
    let id = path_id(&raw, "calibration")?;
    let f: SignForm = serde_urlencoded::from_bytes(&body).unwrap_or_default();
    if cross_site(&headers) || !same_secret(&viewer.csrf, &f.csrf) {
        return Err(Problem::forbidden(
            "this form did not carry the session's CSRF token; reload the page and try again",
        )
        .into());
    }
    let (signer, _) = authenticate(&state, f.token.trim(), client.map(|c| c.0)).await?;
    if signer.id != viewer.principal.id {
        return Err(Problem::forbidden(
            "the token typed is not the one this session was signed in with: sign with your own",
        )
        .into());
    }
    let action = Action::parse(&f.act)
        .ok_or_else(|| Problem::bad_request("choose approve, reject or withdraw"))?;
    let comment = Some(f.comment.trim().to_owned()).filter(|c| !c.is_empty());
    // The same bodies, and so the same checks, as the API's.
    let now = Timestamp::now();
    let act: Act = match action {
        Action::Approve | Action::Reject => ReviewBody {
            decision: if action == Action::Approve {
                Decision::Approve
            } else {
                Decision::Reject
            },
            comment,
        }
        .act(signer, now)
        .map_err(Problem::from)?,
        Action::Supersede | Action::Confirm | Action::Hold => {
            return Err(Problem::bad_request(
                "choose approve, reject or withdraw (a calibration is superseded by \
                 POST /v1/calibrations/{id}/supersede, reprocessed by …/reprocess, held by a \
                 standard's nonconformity)",
            )
            .into());
        }
        Action::Withdraw => WithdrawBody {
            reason: comment.unwrap_or_default(),
        }
        .act(signer, now)
        .map_err(Problem::from)?,
    };
    let issuing = issuing(&state, &headers, id, &act).await;
    review::record(&state.lab, id, act, issuing)
        .await
        .map_err(Problem::from)?;
    Ok(Redirect::to(&format!("/ui/calibrations/{id}#review")).into_response())
}
