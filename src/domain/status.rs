//! A sensor's calibration status, from its latest calibration's verdict and
//! due date:
//!
//! * `failed` — the latest calibration's verdict is fail;
//! * otherwise `unknown` — no due date (the latest calibration was made
//!   without a sensor type);
//! * otherwise `overdue` — the due date has passed;
//! * otherwise `due_soon` — it falls within [`DUE_SOON_DAYS`];
//! * otherwise `ok`.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::timestamp::Timestamp;

/// How close a due date counts as "due soon", in days.
pub const DUE_SOON_DAYS: i64 = 30;

/// A sensor's calibration status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = SensorStatus)]
pub enum Status {
    /// The latest verdict is fail.
    Failed,
    /// Past its due date.
    Overdue,
    /// Due within 30 days.
    DueSoon,
    /// Calibrated and not yet due.
    Ok,
    /// No due date (untyped).
    Unknown,
}

impl Status {
    /// Every status.
    pub const ALL: [Status; 5] = [
        Status::Failed,
        Status::Overdue,
        Status::DueSoon,
        Status::Ok,
        Status::Unknown,
    ];

    /// The wire name.
    pub const fn as_str(self) -> &'static str {
        match self {
            Status::Failed => "failed",
            Status::Overdue => "overdue",
            Status::DueSoon => "due_soon",
            Status::Ok => "ok",
            Status::Unknown => "unknown",
        }
    }

    /// Parses a wire name.
    pub fn parse(s: &str) -> Option<Status> {
        Status::ALL.into_iter().find(|x| x.as_str() == s)
    }

    /// The status of a sensor whose latest calibration had verdict
    /// `verdict_failed` and due date `due_at`, at `now`. (The stores compute
    /// the same in SQL, to filter; the conformance suite checks they agree.)
    pub fn of(verdict_failed: bool, due_at: Option<Timestamp>, now: Timestamp) -> Status {
        match due_at {
            _ if verdict_failed => Status::Failed,
            None => Status::Unknown,
            Some(due) if due < now => Status::Overdue,
            Some(due) if due < now.plus_seconds(DUE_SOON_DAYS * 86_400) => Status::DueSoon,
            Some(_) => Status::Ok,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The order of the rule, and its edges: due exactly now is not yet
    /// overdue; due exactly 30 days on is no longer due soon.
    #[test]
    fn status_follows_the_verdict_then_the_due_date() {
        let now = Timestamp::parse("2026-06-01T00:00:00Z").unwrap();
        let day = 86_400;
        let later = |s: i64| Some(now.plus_seconds(s));
        assert_eq!(Status::of(true, None, now), Status::Failed);
        assert_eq!(Status::of(true, later(400 * day), now), Status::Failed);
        assert_eq!(Status::of(false, None, now), Status::Unknown);
        assert_eq!(Status::of(false, later(-day), now), Status::Overdue);
        assert_eq!(Status::of(false, later(-1), now), Status::Overdue);
        assert_eq!(Status::of(false, later(0), now), Status::DueSoon);
        assert_eq!(Status::of(false, later(30 * day - 1), now), Status::DueSoon);
        assert_eq!(Status::of(false, later(30 * day), now), Status::Ok);
        assert_eq!(Status::of(false, later(365 * day), now), Status::Ok);
    }
}
