//! A calibration's review as its page and certificate show it: its state,
//! its signatures with what each means, the notice of a withdrawn,
//! superseded or held one, its audit trail, and — for a reviewer — the form
//! that signs an approval, rejection or withdrawal (issue 28), posted to
//! [`super::sign`].

use maud::{Markup, html};

use super::badge;
use super::stored::when;
use super::viewer::Viewer;
use crate::domain::auth::Role;
use crate::domain::review::{Action, MAX_COMMENT_CHARS, Signature, State as ReviewState};

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
