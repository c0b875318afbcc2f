//! Whether a control system should use a calibration's coefficients: the
//! sensor's status from that calibration ([`super::status`]) and the reasons
//! not to use them.
//!
//! Coefficients are **not usable** when their calibration's verdict against
//! the sensor type's limits is fail, or when its due date has passed (the
//! sensor is overdue: nothing vouches for them any more). A calibration made
//! without a sensor type was judged against nothing: its status is
//! `unknown`, and its coefficients are usable (the lab chose not to limit
//! them). The answer changes with time only at the due date and 30 days
//! before it ([`Usability::valid_until`]).

use accelcal_core::decision::Verdict;
use serde::Serialize;
use utoipa::ToSchema;

use super::review::{Basis, State};
use super::status::{DUE_SOON_DAYS, Status};
use super::timestamp::Timestamp;

/// Why coefficients are not to be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Reason {
    /// The calibration's verdict is fail.
    Failed,
    /// Its due date has passed.
    Overdue,
    /// The calibration was withdrawn.
    Withdrawn,
    /// The calibration was rejected in review.
    Rejected,
    /// The calibration was superseded by a corrected one.
    Superseded,
    /// The calibration is not approved, and only approved ones are used
    /// (`--require-approval`).
    NotApproved,
    /// The calibration is under review: a reference standard it was made
    /// with was found nonconforming.
    UnderReview,
}

/// One reason, with what it means for this calibration.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, ToSchema)]
pub struct Unusable {
    /// The reason.
    pub reason: Reason,
    /// In words.
    pub detail: String,
}

/// The status and usability of one calibration's coefficients at a time.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, ToSchema)]
pub struct Usability {
    /// The sensor's status if this calibration is its latest.
    pub status: Status,
    /// Whether a control system may use the coefficients.
    pub usable: bool,
    /// Why not (empty when usable).
    pub reasons: Vec<Unusable>,
}

impl Usability {
    /// The usability, at `now`, of coefficients whose calibration had
    /// `verdict` and is due at `due_at`.
    pub fn of(verdict: Option<Verdict>, due_at: Option<Timestamp>, now: Timestamp) -> Self {
        let failed = verdict == Some(Verdict::Fail);
        let mut reasons = Vec::new();
        if failed {
            reasons.push(Unusable {
                reason: Reason::Failed,
                detail: "its calibration's verdict against the sensor type's limits is fail"
                    .to_owned(),
            });
        }
        // Overdue by the status rule itself, whatever the verdict.
        if let Some(due) = due_at.filter(|_| Status::of(false, due_at, now) == Status::Overdue) {
            reasons.push(Unusable {
                reason: Reason::Overdue,
                detail: format!("its calibration was due again at {due}"),
            });
        }
        Usability {
            status: Status::of(failed, due_at, now),
            usable: reasons.is_empty(),
            reasons,
        }
    }

    /// The same, for a calibration in `state` when `basis` decides which
    /// are used: one that does not count on it is not usable either, nor is
    /// one under review.
    pub fn in_state(mut self, state: State, basis: Basis) -> Self {
        let (reason, detail) = match state {
            State::UnderReview => (
                Reason::UnderReview,
                "its calibration is under review: a reference standard it was made with was \
                 found nonconforming",
            ),
            _ if state.counts(basis) => return self,
            State::Withdrawn => (Reason::Withdrawn, "its calibration was withdrawn"),
            State::Rejected => (Reason::Rejected, "its calibration was rejected in review"),
            State::Superseded => (
                Reason::Superseded,
                "its calibration was superseded by a corrected one",
            ),
            State::Submitted | State::Approved => (
                Reason::NotApproved,
                "its calibration is not approved, and only approved calibrations are used",
            ),
        };
        self.reasons.push(Unusable {
            reason,
            detail: detail.to_owned(),
        });
        self.usable = false;
        self
    }

    /// The last instant up to which [`Usability::of`] answers as it does at
    /// `now`: 30 days before the due date (due soon after it) or the due
    /// date (overdue after it); `None` when the answer never changes.
    pub fn valid_until(due_at: Option<Timestamp>, now: Timestamp) -> Option<Timestamp> {
        let due = due_at?;
        [due.plus_seconds(-DUE_SOON_DAYS * 86_400), due]
            .into_iter()
            .find(|t| *t >= now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: &str) -> Timestamp {
        Timestamp::parse(s).unwrap()
    }

    #[test]
    fn calibrations_that_do_not_count_are_not_usable() {
        let now = at("2026-06-01T00:00:00Z");
        let good = || Usability::of(Some(Verdict::Pass), None, now);
        let cases = [
            (State::Submitted, Basis::NotRejected, None),
            (State::Approved, Basis::NotRejected, None),
            (State::Approved, Basis::ApprovedOnly, None),
            (
                State::Submitted,
                Basis::ApprovedOnly,
                Some(Reason::NotApproved),
            ),
            (
                State::Withdrawn,
                Basis::NotRejected,
                Some(Reason::Withdrawn),
            ),
            (
                State::Withdrawn,
                Basis::ApprovedOnly,
                Some(Reason::Withdrawn),
            ),
            (State::Rejected, Basis::NotRejected, Some(Reason::Rejected)),
        ];
        for (state, basis, reason) in cases {
            let u = good().in_state(state, basis);
            assert_eq!(u.usable, reason.is_none(), "{state:?} on {basis:?}");
            assert_eq!(u.reasons.first().map(|r| r.reason), reason);
            // The status is the calibration's, whatever its state.
            assert_eq!(u.status, good().status);
        }
    }

    #[test]
    fn failed_and_overdue_are_not_usable_and_say_why() {
        let now = at("2026-06-01T00:00:00Z");
        let due = |s| Some(at(s));
        let u = Usability::of(Some(Verdict::Pass), due("2027-01-01T00:00:00Z"), now);
        assert_eq!((u.status, u.usable, u.reasons.len()), (Status::Ok, true, 0));
        let u = Usability::of(Some(Verdict::Conditional), due("2026-06-20T00:00:00Z"), now);
        assert_eq!((u.status, u.usable), (Status::DueSoon, true));
        let u = Usability::of(Some(Verdict::Pass), due("2026-05-31T23:59:59Z"), now);
        assert_eq!((u.status, u.usable), (Status::Overdue, false));
        assert_eq!(u.reasons[0].reason, Reason::Overdue);
        assert!(
            u.reasons[0].detail.contains("2026-05-31T23:59:59"),
            "{:?}",
            u.reasons
        );
        // Due exactly now is not yet overdue (as the status rule says).
        assert!(Usability::of(None, Some(now), now).usable);
        let u = Usability::of(Some(Verdict::Fail), due("2020-01-01T00:00:00Z"), now);
        assert_eq!(u.status, Status::Failed);
        let reasons: Vec<Reason> = u.reasons.iter().map(|r| r.reason).collect();
        assert_eq!(reasons, [Reason::Failed, Reason::Overdue]);
        // Untyped: judged against nothing, status unknown, usable.
        let u = Usability::of(None, None, now);
        assert_eq!((u.status, u.usable), (Status::Unknown, true));
    }

    #[test]
    fn the_answer_holds_until_due_soon_or_due() {
        let due = at("2026-07-01T00:00:00Z");
        let soon = at("2026-06-01T00:00:00Z");
        assert_eq!(Usability::valid_until(None, soon), None);
        assert_eq!(
            Usability::valid_until(Some(due), at("2026-01-01T00:00:00Z")),
            Some(soon)
        );
        assert_eq!(Usability::valid_until(Some(due), soon), Some(soon));
        assert_eq!(
            Usability::valid_until(Some(due), at("2026-06-02T00:00:00Z")),
            Some(due)
        );
        assert_eq!(
            Usability::valid_until(Some(due), at("2026-07-01T00:00:01Z")),
            None
        );
        // Right up to the instant, and different a second after it.
        let of = |t: Timestamp| Usability::of(Some(Verdict::Pass), Some(due), t).status;
        assert_eq!(of(soon), Status::Ok);
        assert_eq!(of(soon.plus_seconds(1)), Status::DueSoon);
        assert_eq!(of(due), Status::DueSoon);
        assert_eq!(of(due.plus_seconds(1)), Status::Overdue);
    }
}
