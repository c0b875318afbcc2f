//! Review of stored calibrations: their state, the acts that change it, who
//! may perform each, and which calibrations count (issue 28).
//!
//! A stored calibration never changes; what happens to it afterwards is a
//! list of signed acts beside it, append-only. Its state is the state the
//! last act left it in, `submitted` before any:
//!
//! ```text
//!             approve            withdraw
//! submitted ───────────▶ approved ───────▶ withdrawn
//!  │  │ reject             │ supersede
//!  │  └──────▶ rejected    └─────────────▶ superseded
//!  └── withdraw ▶ withdrawn, supersede ▶ superseded
//!
//! submitted, approved ──hold──▶ under_review ──approve──▶ approved
//!                                    └── withdraw, supersede as above
//! ```
//!
//! * `approve` and `reject` are a reviewer's decision on a `submitted`
//!   calibration, by someone other than who submitted it ([`Identity`]);
//! * `withdraw` takes a calibration that counts (`submitted` or
//!   `approved`) out of use for good, with a reason; the one who submitted
//!   it may withdraw it (a reviewer taking back their own error vouches for
//!   nothing);
//! * `supersede` replaces a calibration that counts by a corrected one,
//!   stored in the same transaction, which records what it supersedes and
//!   why: a reviewer or admin may, and so may the very token that submitted
//!   it within [`SUPERSEDE_WINDOW_SECONDS`] of its submission (a station
//!   correcting its own upload before anyone relied on it);
//! * `confirm` records that the stored submission, computed again with the
//!   current method, gave every number the same; it keeps the state;
//! * `hold` (an admin's, for a nonconformity of a reference standard the
//!   calibration was made with, or placed as it is stored inside a
//!   nonconformity's window) puts it `under_review`: it still counts, but
//!   its coefficients are not usable until a reviewer records a disposition
//!   — approves it again (not the one who submitted it) with the reason in
//!   its comment (`no effect: …`) — or withdraws or supersedes it (a
//!   correction still using the standard is held in turn);
//! * `rejected`, `withdrawn` and `superseded` are final.
//!
//! Which calibrations a reader uses is the [`Basis`]: every calibration not
//! rejected, withdrawn or superseded, or (with `--require-approval`)
//! approved ones only.

pub use super::limits::MAX_COMMENT_CHARS;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::auth::{Principal, Role};
use super::field::Invalid;
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// How long after a submission the station token that made it may
/// supersede it itself (24 h); afterwards a reviewer does.
pub const SUPERSEDE_WINDOW_SECONDS: i64 = 24 * 3600;

/// What a superseding calibration records of the one it replaces.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct Supersedes {
    /// The calibration (and certificate number) it replaces.
    pub calibration_id: uuid::Uuid,
    /// Why.
    pub reason: String,
}

/// A reviewer's decision (`POST /v1/calibrations/{id}/review`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
#[schema(as = ReviewDecision)]
pub enum Decision {
    /// Release the results for use.
    Approve,
    /// The results are not to be used.
    Reject,
}

/// The body of `POST /v1/calibrations/{id}/review`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ReviewBody {
    /// `approve` or `reject`.
    pub decision: Decision,
    /// The reviewer's comment: optional when approving, required when
    /// rejecting (why); at most 2 000 characters.
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_comment)]
    pub comment: Option<String>,
}

/// The body of `POST /v1/calibrations/{id}/withdraw`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WithdrawBody {
    /// Why it is withdrawn (printed on its certificate); at most 2 000
    /// characters.
    #[schema(schema_with = crate::domain::schema::reason)]
    pub reason: String,
}

/// A comment or reason, checked: `required` ones may not be absent.
fn comment(text: Option<String>, field: &str, required: bool) -> Result<Option<String>, Invalid> {
    match text {
        None if required => Err(Invalid::one(format!("/{field}"), "is required: say why")),
        None => Ok(None),
        Some(t) => check_str(t.trim(), MAX_COMMENT_CHARS, Chars::Text)
            .map(|()| Some(t.trim().to_owned()))
            .map_err(|why| Invalid::one(format!("/{field}"), why)),
    }
}

/// The reason of a supersession (a query parameter), checked: present,
/// free text, at most [`MAX_COMMENT_CHARS`].
pub fn check_reason(text: Option<&str>) -> Result<String, String> {
    let t = text.map(str::trim).unwrap_or_default();
    check_str(t, MAX_COMMENT_CHARS, Chars::Text)
        .map(|()| t.to_owned())
        .map_err(|why| format!("the reason {why}"))
}

/// The supersession of a calibration by the corrected one `by`, signed by
/// `signer` at `at`, for `reason` (checked by [`check_reason`]).
pub fn supersession(reason: String, signer: Principal, at: Timestamp, by: uuid::Uuid) -> Act {
    Act {
        action: Action::Supersede,
        signer,
        at,
        comment: Some(reason),
        superseded_by: Some(by),
    }
}

impl ReviewBody {
    /// The act it asks for, signed by `signer` at `at`.
    pub fn act(self, signer: Principal, at: Timestamp) -> Result<Act, Invalid> {
        let action = match self.decision {
            Decision::Approve => Action::Approve,
            Decision::Reject => Action::Reject,
        };
        Ok(Act {
            action,
            signer,
            at,
            comment: comment(self.comment, "comment", action == Action::Reject)?,
            superseded_by: None,
        })
    }
}

impl WithdrawBody {
    /// The withdrawal it asks for, signed by `signer` at `at`.
    pub fn act(self, signer: Principal, at: Timestamp) -> Result<Act, Invalid> {
        Ok(Act {
            action: Action::Withdraw,
            signer,
            at,
            comment: comment(Some(self.reason), "reason", true)?,
            superseded_by: None,
        })
    }
}

/// Where a calibration stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum State {
    /// Stored, not yet reviewed.
    Submitted,
    /// Approved by a reviewer.
    Approved,
    /// Rejected by a reviewer: never counts.
    Rejected,
    /// Withdrawn: kept, but no longer anyone's latest, baseline or point.
    Withdrawn,
    /// Replaced by a corrected calibration: kept, and no longer counts.
    Superseded,
    /// Made with a reference standard later found nonconforming: it counts
    /// as before, but its coefficients are not usable until a reviewer
    /// approves it again or withdraws it (issue 29, reverse trace).
    #[serde(rename = "under_review")]
    UnderReview,
}

impl State {
    /// Every state, in declaration order.
    pub const ALL: [State; 6] = [
        State::Submitted,
        State::Approved,
        State::Rejected,
        State::Withdrawn,
        State::Superseded,
        State::UnderReview,
    ];

    /// The wire and stored name.
    pub fn as_str(self) -> &'static str {
        match self {
            State::Submitted => "submitted",
            State::Approved => "approved",
            State::Rejected => "rejected",
            State::Withdrawn => "withdrawn",
            State::Superseded => "superseded",
            State::UnderReview => "under_review",
        }
    }

    /// Parses a stored name.
    pub fn parse(s: &str) -> Option<State> {
        State::ALL.into_iter().find(|x| x.as_str() == s)
    }

    /// Whether a calibration in this state is used on `basis`.
    pub fn counts(self, basis: Basis) -> bool {
        match basis {
            Basis::NotRejected => matches!(
                self,
                State::Submitted | State::Approved | State::UnderReview
            ),
            Basis::ApprovedOnly => self == State::Approved,
        }
    }
}

/// An act that changes a calibration's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Action {
    /// A reviewer approves it.
    Approve,
    /// A reviewer rejects it.
    Reject,
    /// A reviewer or admin withdraws it.
    Withdraw,
    /// A corrected calibration replaces it.
    Supersede,
    /// Its submission, computed again with the current method, gave every
    /// number the same (the state is kept).
    Confirm,
    /// An admin places it under review: a reference standard it was made
    /// with was found nonconforming (`POST /v1/standards/{id}/nonconformity`).
    Hold,
}

impl Action {
    /// The stored name.
    pub fn as_str(self) -> &'static str {
        match self {
            Action::Approve => "approve",
            Action::Reject => "reject",
            Action::Withdraw => "withdraw",
            Action::Supersede => "supersede",
            Action::Confirm => "confirm",
            Action::Hold => "hold",
        }
    }

    /// Parses a stored name.
    pub fn parse(s: &str) -> Option<Action> {
        [
            Action::Approve,
            Action::Reject,
            Action::Withdraw,
            Action::Supersede,
            Action::Confirm,
            Action::Hold,
        ]
        .into_iter()
        .find(|a| a.as_str() == s)
    }

    /// The state the act moves a calibration in `state` to.
    pub fn target(self, state: State) -> State {
        match self {
            Action::Approve => State::Approved,
            Action::Reject => State::Rejected,
            Action::Withdraw => State::Withdrawn,
            Action::Supersede => State::Superseded,
            Action::Confirm => state,
            Action::Hold => State::UnderReview,
        }
    }

    /// What signing it means, in the words the pages and the certificate
    /// print beside the signature.
    pub fn meaning(self) -> &'static str {
        match self {
            Action::Approve => "Approved: the results were reviewed and are released for use",
            Action::Reject => "Rejected: the results were reviewed and are not to be used",
            Action::Withdraw => "Withdrawn: the results are no longer to be used",
            Action::Supersede => {
                "Superseded: replaced by a corrected calibration, whose results are to be used instead"
            }
            Action::Confirm => {
                "Confirmed: computed again from the stored submission with the current method, every number the same"
            }
            Action::Hold => {
                "Placed under review: a reference standard it was made with was found nonconforming; its results are not to be used until approved again or withdrawn"
            }
        }
    }
}

/// Which calibrations coefficients, compensation, as-found and stability use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Basis {
    /// Every calibration not rejected, withdrawn or superseded (the
    /// default).
    #[default]
    NotRejected,
    /// Approved calibrations only (`--require-approval`).
    ApprovedOnly,
}

/// The person behind a token, for the rule that nobody reviews their own
/// work: the holder's name when the token names one, the token otherwise.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Identity {
    /// A named holder.
    Holder(String),
    /// A token without a holder (or the configured admin token).
    Token(String),
}

impl Identity {
    /// Who holds the token `token_id` (its holder when it names one).
    pub fn of(token_id: &str, holder: Option<&str>) -> Identity {
        match holder {
            Some(h) => Identity::Holder(h.to_owned()),
            None => Identity::Token(token_id.to_owned()),
        }
    }

    /// Whether two identities are the same person: the same holder name, or
    /// the same token.
    fn same(&self, token_id: &str, other: &Identity, other_token: &str) -> bool {
        token_id == other_token || self == other
    }
}

/// One signed act on a calibration.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Signature {
    /// Its place in the calibration's list, from 1.
    #[schema(minimum = 1)]
    pub seq: u32,
    /// What was done.
    pub action: Action,
    /// The state it moved the calibration to.
    pub state: State,
    /// What signing it means.
    pub meaning: String,
    /// The signing token's id (`env-admin` for the configured admin token).
    pub token_id: String,
    /// The signing token's role.
    pub role: Role,
    /// The person who holds that token, if it names one.
    pub holder: Option<String>,
    /// When it was signed.
    pub signed_at: Timestamp,
    /// The reviewer's comment, or the reason of a withdrawal or
    /// supersession.
    pub comment: Option<String>,
    /// For a supersession: the calibration that replaces this one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub superseded_by: Option<uuid::Uuid>,
}

/// A signature about to be recorded: the act and who signs it, when.
#[derive(Clone, Debug, PartialEq)]
pub struct Act {
    /// What is done.
    pub action: Action,
    /// Who signs.
    pub signer: Principal,
    /// When.
    pub at: Timestamp,
    /// Comment or reason.
    pub comment: Option<String>,
    /// For a supersession: the calibration that replaces the one acted on.
    pub superseded_by: Option<uuid::Uuid>,
}

/// Who submitted a calibration, and when; and who submitted the
/// calibrations it replaces.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Submitter {
    /// The submitting token's id.
    pub token_id: String,
    /// Its holder, if it named one.
    pub holder: Option<String>,
    /// When accelcal received it.
    pub received_at: Timestamp,
    /// For a calibration that supersedes others (a correction, a
    /// reprocessing): the token and holder that submitted each calibration
    /// it replaces, directly or through earlier supersessions, nearest
    /// first — the last is the measurement's author. Nobody among them may
    /// approve or reject it either.
    pub earlier: Vec<(String, Option<String>)>,
}

impl Submitter {
    /// Who may not review the calibration: its submitter and everyone who
    /// submitted a calibration it replaces (the author included).
    fn authors(&self) -> impl Iterator<Item = (&str, Identity)> {
        std::iter::once((self.token_id.as_str(), self.holder.as_deref()))
            .chain(self.earlier.iter().map(|(t, h)| (t.as_str(), h.as_deref())))
            .map(|(t, h)| (t, Identity::of(t, h)))
    }
}

/// Why an act is refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// The signer's role does not allow the act.
    #[error(
        "a {role} token may not {verb} this calibration: it takes a reviewer or admin token \
         (or, to supersede, the token that submitted it, within 24 h)"
    )]
    Role {
        /// The signer's role.
        role: Role,
        /// The act.
        verb: &'static str,
    },
    /// The signer submitted the calibration, or one it replaces.
    #[error(
        "the calibration, or one it replaces, was submitted by the same person ({who}); another \
         reviewer must {verb} it"
    )]
    OwnWork {
        /// The holder or token.
        who: String,
        /// The act.
        verb: &'static str,
    },
    /// A hold released without a recorded disposition.
    #[error(
        "the calibration is under review (held: a reference standard it was made with was \
         found nonconforming); approving it releases the hold, which takes the disposition \
         in `comment` — why the nonconformity has no effect on it (`no effect: …`) or what \
         was done (re-measured, …)"
    )]
    Disposition,
    /// A temperature model that counts was fitted from the calibration
    /// (its `from_calibrations`): rejecting, withdrawing or superseding the
    /// calibration would leave the model's coefficients standing on a
    /// measurement that no longer counts.
    #[error(
        "temperature model {model} was fitted from this calibration and still counts: reject \
         or withdraw the model first, then fit it again from the calibrations that stand"
    )]
    FittedInto {
        /// The model.
        model: uuid::Uuid,
    },
    /// The calibration's state does not allow the act.
    #[error("the calibration is {}: only a {from} calibration can be {}", .state.as_str(), .target_past)]
    State {
        /// Its state.
        state: State,
        /// What the act would have made it.
        target_past: &'static str,
        /// The states it can be done from, in words.
        from: &'static str,
    },
}

impl Refusal {
    /// Whether it is a matter of permission (403) rather than of the
    /// calibration's state (409) or the act's content (422).
    pub fn is_permission(&self) -> bool {
        matches!(self, Refusal::Role { .. } | Refusal::OwnWork { .. })
    }
}

impl Act {
    /// The signature this act records on a calibration in `state`
    /// submitted by `submitter`, as the `seq`-th — or why it may not be
    /// recorded.
    pub fn check(
        &self,
        state: State,
        submitter: &Submitter,
        seq: u32,
    ) -> Result<Signature, Refusal> {
        let verb = self.action.as_str();
        // The submitting token may supersede its own calibration within the
        // window; otherwise it takes a reviewer.
        let own_correction = self.action == Action::Supersede
            && self.signer.id == submitter.token_id
            && self.at <= submitter.received_at.plus_seconds(SUPERSEDE_WINDOW_SECONDS);
        let needs = if self.action == Action::Hold {
            Role::Admin
        } else {
            Role::Reviewer
        };
        if self.signer.role < needs && !own_correction {
            return Err(Refusal::Role {
                role: self.signer.role,
                verb,
            });
        }
        let (allowed, from) = match self.action {
            Action::Approve => (
                matches!(state, State::Submitted | State::UnderReview),
                "submitted or under-review",
            ),
            Action::Reject => (state == State::Submitted, "submitted"),
            Action::Hold => (
                matches!(state, State::Submitted | State::Approved),
                "submitted or approved",
            ),
            Action::Withdraw | Action::Supersede | Action::Confirm => (
                matches!(
                    state,
                    State::Submitted | State::Approved | State::UnderReview
                ),
                "submitted, approved or under-review",
            ),
        };
        if !allowed {
            return Err(Refusal::State {
                state,
                target_past: match self.action {
                    Action::Confirm => "confirmed",
                    Action::Hold => "placed under review",
                    other => other.target(state).as_str(),
                },
                from,
            });
        }
        let signer = Identity::of(&self.signer.id, self.signer.holder.as_deref());
        if matches!(self.action, Action::Approve | Action::Reject)
            && let Some((_, author)) = submitter
                .authors()
                .find(|(token, author)| signer.same(&self.signer.id, author, token))
        {
            let who = match author {
                Identity::Holder(h) => h,
                Identity::Token(t) => format!("token {t}"),
            };
            return Err(Refusal::OwnWork { who, verb });
        }
        if self.action == Action::Approve && state == State::UnderReview && self.comment.is_none() {
            return Err(Refusal::Disposition);
        }
        Ok(Signature {
            seq,
            action: self.action,
            state: self.action.target(state),
            meaning: self.action.meaning().to_owned(),
            token_id: self.signer.id.clone(),
            role: self.signer.role,
            holder: self.signer.holder.clone(),
            signed_at: self.at,
            comment: self.comment.clone(),
            superseded_by: self.superseded_by,
        })
    }
}

#[cfg(test)]
mod tests;
