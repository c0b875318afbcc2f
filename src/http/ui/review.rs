//! A calibration's review on its page: its state, its signatures with
//! what each means, and — for a reviewer — the form that signs an
//! approval, rejection or withdrawal (issue 28).
//!
//! Signing is an act, not a side effect of being signed in: the form asks
//! for the token again, and it must be the token the session was opened
//! with. The form also carries the session's CSRF token and is refused when
//! the browser says it came from another site.

use axum::extract::{Extension, Path, State};
use axum::http::HeaderMap;
use axum::response::{IntoResponse, Redirect, Response};
use bytes::Bytes;
use maud::{Markup, html};
use serde::Deserialize;

use super::calibration::when;
use super::issue::issuing;
use super::session::{Viewer, cross_site};
use super::{UiError, badge};
use crate::app::review;
use crate::domain::auth::Role;
use crate::domain::review::{
    Act, Action, Decision, MAX_COMMENT_CHARS, ReviewBody, Signature, State as ReviewState,
    WithdrawBody,
};
use crate::domain::session::same_secret;
use crate::domain::timestamp::Timestamp;
use crate::http::auth::{ClientAddr, authenticate};
use crate::http::problem::Problem;
use crate::http::{AppState, path_id};

/// The badge of a state.
pub fn state_badge(state: ReviewState) -> Markup {
    let class = match state {
        ReviewState::Approved => "pass",
        ReviewState::Rejected | ReviewState::Withdrawn | ReviewState::Superseded => "fail",
        ReviewState::UnderReview => "conditional",
        ReviewState::Submitted => "unknown",
    };
    badge(class, state.as_str())
}

/// Who signed, as printed: the holder's name, or the token's id.
pub fn signer(s: &Signature) -> String {
    match &s.holder {
        Some(h) => h.clone(),
        None => format!("token {}", s.token_id),
    }
}

/// The notice a withdrawn, rejected or superseded calibration carries on
/// its page and on every page of its certificate: the act, and why.
pub fn notice(state: ReviewState, signatures: &[Signature]) -> Option<String> {
    let last = signatures.iter().rev().find(|s| s.state == state)?;
    let why = last.comment.as_deref().unwrap_or("no reason given");
    match state {
        ReviewState::Withdrawn => Some(format!(
            "WITHDRAWN {} by {}: {why}",
            when(&last.signed_at.to_string()),
            signer(last)
        )),
        ReviewState::Rejected => Some(format!(
            "REJECTED in review {} by {}: {why}",
            when(&last.signed_at.to_string()),
            signer(last)
        )),
        ReviewState::Superseded => Some(format!(
            "SUPERSEDED {} by {} (signed by {}): {why}",
            when(&last.signed_at.to_string()),
            last.superseded_by.map_or_else(
                || "a corrected calibration".to_owned(),
                |id| format!("certificate No. {id}")
            ),
            signer(last)
        )),
        ReviewState::UnderReview => Some(format!(
            "UNDER REVIEW since {} ({}): {why}; its results are not to be used until a \
             reviewer approves it again or withdraws it",
            when(&last.signed_at.to_string()),
            signer(last)
        )),
        ReviewState::Submitted | ReviewState::Approved => None,
    }
}

/// The signatures as a table (also on the certificate).
pub fn signatures_table(signatures: &[Signature]) -> Markup {
    html! {
        div.table-wrap tabindex="0" role="region" aria-label="Signatures" {
            table #signatures {
                caption { "Signatures, in order" }
                thead { tr {
                    th scope="col" { "Signed by" }
                    th scope="col" { "Role" }
                    th scope="col" { "When" }
                    th scope="col" { "Meaning" }
                    th scope="col" { "Comment or reason" }
                } }
                tbody {
                    @for s in signatures {
                        tr data-action=(s.action.as_str()) {
                            td { (signer(s)) }
                            td { (s.role.as_str()) }
                            td { (when(&s.signed_at.to_string())) }
                            td { (s.meaning) }
                            td { (s.comment.as_deref().unwrap_or("—")) }
                        }
                    }
                }
            }
        }
    }
}

/// The review section of a calibration's page.
pub fn section(id: &str, state: ReviewState, signatures: &[Signature], viewer: &Viewer) -> Markup {
    let may_sign = viewer.principal.role >= Role::Reviewer;
    let actions: &[(Action, &str)] = match state {
        ReviewState::Submitted => &[
            (Action::Approve, "Approve: release the results for use"),
            (Action::Reject, "Reject: the results are not to be used"),
            (Action::Withdraw, "Withdraw: take the results out of use"),
        ],
        ReviewState::Approved => &[(Action::Withdraw, "Withdraw: take the results out of use")],
        ReviewState::UnderReview => &[
            (
                Action::Approve,
                "Approve again: the results were reviewed against the nonconformity and stand",
            ),
            (Action::Withdraw, "Withdraw: take the results out of use"),
        ],
        ReviewState::Rejected | ReviewState::Withdrawn | ReviewState::Superseded => &[],
    };
    html! {
        section #review aria-labelledby="review-title" {
            h2 #review-title { "Review" }
            p { "State " (state_badge(state)) }
            @if signatures.is_empty() {
                p.muted { "Not reviewed yet." }
            } @else {
                (signatures_table(signatures))
            }
            @if may_sign && !actions.is_empty() {
                form.review method="post" action={"/ui/calibrations/" (id) "/review"} {
                    input type="hidden" name="csrf" value=(viewer.csrf);
                    fieldset {
                        legend { "Sign" }
                        @for (k, (action, label)) in actions.iter().enumerate() {
                            label {
                                input type="radio" name="act" value=(action.as_str()) required checked[k == 0];
                                " " (label)
                            }
                        }
                    }
                    label for="review-comment" {
                        "Comment (required to reject; the reason, required to withdraw)"
                        textarea id="review-comment" name="comment" rows="3" maxlength=(MAX_COMMENT_CHARS) {}
                    }
                    label for="review-token" {
                        "Your token, again: signing is an act of yours"
                        input id="review-token" name="token" type="password" required
                            autocomplete="current-password" spellcheck="false" placeholder="acc_…";
                    }
                    button type="submit" { "Sign" }
                }
            }
        }
    }
}

/// A calibration's own audit trail (for reviewers and admins): every
/// entry about it, with the first characters of its hash.
pub fn trail(entries: &[crate::domain::audit::Entry]) -> Markup {
    html! {
        section #trail aria-labelledby="trail-title" {
            h2 #trail-title { "Audit trail" }
            p.muted { "Entries of the tamper-evident trail about this calibration; "
                "the whole trail is at " code { "GET /v1/audit" } "." }
            div.table-wrap tabindex="0" role="region" aria-label="Audit trail" {
                table #audit {
                    caption { "Audit entries, in order" }
                    thead { tr {
                        th scope="col" { "No." }
                        th scope="col" { "When" }
                        th scope="col" { "Who" }
                        th scope="col" { "Role" }
                        th scope="col" { "Action" }
                        th scope="col" { "Hash" }
                    } }
                    tbody {
                        @for e in entries {
                            tr data-action=(e.action) {
                                td.num { (e.seq) }
                                td { (when(&e.at.to_string())) }
                                td { (e.actor.holder.clone().unwrap_or_else(|| format!("token {}", e.actor.token_id))) }
                                td { (e.actor.role) }
                                td { (e.action) }
                                td { code title=(e.hash) { (e.hash.get(..12).unwrap_or(&e.hash)) "…" } }
                            }
                        }
                    }
                }
            }
        }
    }
}

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
