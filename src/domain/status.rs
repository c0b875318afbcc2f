//! A sensor's calibration status, from its latest calibration's verdict and
//! due date:
//!
//! * `failed` — the latest calibration's verdict is fail;
//! * otherwise `unknown` — no due date (the latest calibration was made
//!   without a sensor type);
//! * otherwise `overdue` — the due date has passed;
//! * otherwise `due_soon` — it falls within [`DUE_SOON_DAYS`];
//! * otherwise `ok`.
//!
//! The rule is written once, as [`RULE`]: [`Status::of`] applies it to a
//! summary in memory, and [`Status::sql`] renders the same table as the SQL
//! `CASE` both engines filter by.

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
    /// `verdict_failed` and due date `due_at`, at `now`: the first line of
    /// [`RULE`] that holds.
    pub fn of(verdict_failed: bool, due_at: Option<Timestamp>, now: Timestamp) -> Status {
        let soon = now.plus_seconds(DUE_SOON_DAYS * 86_400);
        let holds = |c: When| match c {
            When::Failed => verdict_failed,
            When::NoDueDate => due_at.is_none(),
            When::DueBeforeNow => due_at.is_some_and(|d| d < now),
            When::DueBeforeSoon => due_at.is_some_and(|d| d < soon),
            When::Otherwise => true,
        };
        RULE.iter()
            .find(|(c, _)| holds(*c))
            .map_or(Status::Ok, |(_, s)| *s)
    }

    /// [`RULE`] as an SQL `CASE` over the sensors row `s` (its
    /// `latest_verdict` and `latest_due_at`), `now` and `soon` being the
    /// query's placeholders for the time of the read and 30 days later.
    pub fn sql(now: &str, soon: &str) -> String {
        let mut case = String::from("CASE");
        for (when, status) in RULE {
            let condition = match when {
                When::Failed => "s.latest_verdict = 'fail'".to_owned(),
                When::NoDueDate => "s.latest_due_at IS NULL".to_owned(),
                When::DueBeforeNow => format!("s.latest_due_at < {now}"),
                When::DueBeforeSoon => format!("s.latest_due_at < {soon}"),
                When::Otherwise => "TRUE".to_owned(),
            };
            case.push_str(&format!(" WHEN {condition} THEN '{}'", status.as_str()));
        }
        case.push_str(" END");
        case
    }
}

/// A condition of the rule, on the latest calibration's verdict and due
/// date and the time of the read.
#[derive(Clone, Copy, Debug)]
pub enum When {
    /// The verdict is fail.
    Failed,
    /// There is no due date.
    NoDueDate,
    /// The due date is before now.
    DueBeforeNow,
    /// The due date is before now + [`DUE_SOON_DAYS`].
    DueBeforeSoon,
    /// Always.
    Otherwise,
}

/// The status rule: the first condition that holds gives the status.
pub const RULE: [(When, Status); 5] = [
    (When::Failed, Status::Failed),
    (When::NoDueDate, Status::Unknown),
    (When::DueBeforeNow, Status::Overdue),
    (When::DueBeforeSoon, Status::DueSoon),
    (When::Otherwise, Status::Ok),
];

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

    /// The SQL is the rule's table, in order (the store conformance suite
    /// runs it on both engines against [`Status::of`]).
    #[test]
    fn the_sql_is_the_table() {
        assert_eq!(
            Status::sql("$1", "$2"),
            "CASE WHEN s.latest_verdict = 'fail' THEN 'failed' \
             WHEN s.latest_due_at IS NULL THEN 'unknown' \
             WHEN s.latest_due_at < $1 THEN 'overdue' \
             WHEN s.latest_due_at < $2 THEN 'due_soon' \
             WHEN TRUE THEN 'ok' END"
        );
    }
}
