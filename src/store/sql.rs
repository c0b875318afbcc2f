//! The SQL both engines share: the one order of a sensor's calibrations,
//! a calibration's state and whether it counts, the window of a history,
//! the sensors' merge and recomputation, the chain of supersessions, the
//! standards a calibration was made with, and earlier submitters — each a
//! fragment spliced into either engine's statements, with its parameters'
//! placeholders given.

use crate::domain::review::{Basis, State};
use crate::domain::timestamp::Timestamp;

/// A sensor's calibrations newest first: by `performed_at`, a tie going to
/// the larger id (UUIDv7, so the later stored). The one order both engines'
/// queries of the latest, the previous and the history use; the sensors'
/// merge ([`SENSOR_MERGE`]) keeps the latest by the same rule.
pub const NEWEST_FIRST: &str = "ORDER BY c.performed_at DESC, c.id DESC";

/// A calibration's state, in SQL over its row `c`: the state its last
/// signature left it in, `submitted` before any
/// ([`crate::domain::review`]). A macro, to be spliced into the engines'
/// column lists at compile time.
#[macro_export]
macro_rules! state_sql {
    () => {
        "coalesce((SELECT s.state FROM signatures s WHERE s.calibration_id = c.id \
         ORDER BY s.seq DESC LIMIT 1), 'submitted')"
    };
}

/// How many calibrations `window` (a condition on `c`) selects, in SQL over
/// the CTE `page` (its newest, at most `limit`): the page's own count when
/// it is not full, so that a series costs the same for a sensor with 40
/// calibrations as with 100 000 until the page is full; the window counted
/// again only then (a count, not a window function over every row's
/// columns: 1.1 s → 47 ms for 100 000, BENCHMARKS.md "History") — unless
/// the window is the sensor's whole history on [`Basis::NotRejected`]
/// (`sensor` names the placeholder of its id), whose count its row keeps
/// ([`SENSOR_MERGE`], [`sensor_recompute`]; `audit verify` checks it): then
/// read there, so that the count costs the same for 10 calibrations as for
/// 100 000 (BENCHMARKS.md "A sensor's history").
pub fn in_window_sql(limit: &str, window: &str, sensor: Option<&str>) -> String {
    let all = match sensor {
        Some(p) => format!("(SELECT s.calibration_count FROM sensors s WHERE s.sensor_id = {p})"),
        None => format!("(SELECT count(*) FROM calibrations c WHERE {window})"),
    };
    format!(
        "CASE WHEN (SELECT count(*) FROM page) < {limit} THEN (SELECT count(*) FROM page) \
         ELSE {all} END"
    )
}

/// Whether a series of `from..=to` on `basis` is the sensor's whole history
/// as its row counts it ([`in_window_sql`]).
pub fn whole_history(from: Option<Timestamp>, to: Option<Timestamp>, basis: Basis) -> bool {
    from.is_none() && to.is_none() && basis == Basis::NotRejected
}

/// Whether calibration `c` counts on `basis`, in SQL: its state
/// ([`state_sql!`]) is none of those [`State::counts`] refuses — the one
/// statement of the rule for every engine's query.
///
/// Written as the complement (`NOT IN` the states that do not count) for
/// PostgreSQL's planner: it cannot estimate a condition on a subquery, and
/// takes `x IN (3 states)` to keep about 1.5 % of the rows (0.5 % per
/// value) but `x NOT IN (…)` about 98.5 %. With the former, a sensor's
/// latest calibration that counts (`… ORDER BY … LIMIT 1`) looks as if it
/// had to read all of the sensor's rows whichever way it goes, and on
/// statistics taken while the table was small the planner picked a bitmap
/// scan of the sensor's whole history and a sort over a backward walk of
/// the index that stops at the first row: 138–158 ms for 13 400 rows
/// instead of one row read (BENCHMARKS.md "A submission's CPU, cut where
/// the profile pointed"). With the latter the walk is the cheaper plan, as
/// it is.
pub fn counts(basis: Basis) -> &'static str {
    match basis {
        Basis::NotRejected => concat!(
            state_sql!(),
            " NOT IN ('rejected', 'withdrawn', 'superseded')"
        ),
        Basis::ApprovedOnly => concat!(
            state_sql!(),
            " NOT IN ('submitted', 'rejected', 'withdrawn', 'superseded', 'under_review')"
        ),
    }
}

/// A sensor's row computed again from the calibrations that count
/// ([`Basis::NotRejected`]), after one stopped counting or changed state;
/// `p` is the engine's placeholder for the sensor's id (`?1`, `$1`). The
/// same answer [`SENSOR_MERGE`] keeps incrementally: count, earliest,
/// latest by [`NEWEST_FIRST`] with its verdict and due date. A sensor
/// none of whose calibrations counts keeps its row with a count of 0 until
/// [`sensor_forget`] removes it.
pub fn sensor_recompute(p: &str) -> String {
    let of = |column: &str| {
        format!(
            "(SELECT c.{column} FROM calibrations c WHERE c.sensor_id = sensors.sensor_id \
             AND {} {NEWEST_FIRST} LIMIT 1)",
            counts(Basis::NotRejected)
        )
    };
    format!(
        "UPDATE sensors SET \
         calibration_count = (SELECT count(*) FROM calibrations c \
           WHERE c.sensor_id = sensors.sensor_id AND {counting}), \
         first_performed_at = coalesce((SELECT min(c.performed_at) FROM calibrations c \
           WHERE c.sensor_id = sensors.sensor_id AND {counting}), first_performed_at), \
         latest_calibration_id = coalesce({id}, latest_calibration_id), \
         latest_performed_at = coalesce({performed}, latest_performed_at), \
         latest_verdict = {verdict}, latest_due_at = {due} \
         WHERE sensor_id = {p}",
        counting = counts(Basis::NotRejected),
        id = of("id"),
        performed = of("performed_at"),
        verdict = of("verdict"),
        due = of("due_at"),
    )
}

/// Whether an act moving a calibration from `before` to `after` (storing
/// a replacement with it or not) changes its sensor's row: only when the
/// set of the sensor's calibrations that count on [`Basis::NotRejected`]
/// (the row's basis) changes — the row is computed from that set and from
/// columns a calibration never changes. An approval, a hold or its release
/// leave the set as it was, and the row is not recomputed: the recompute
/// reads every calibration of the sensor (BENCHMARKS.md "A sensor's
/// history").
pub fn changes_the_sensor(before: State, after: State, replaced: bool) -> bool {
    replaced || before.counts(Basis::NotRejected) != after.counts(Basis::NotRejected)
}

/// The id of sensor `p`'s latest approved calibration by [`NEWEST_FIRST`]:
/// what its reads serve with `--require-approval` (`id`).
pub fn latest_approved_id_sql(p: &str) -> String {
    format!(
        "SELECT c.id FROM calibrations c WHERE c.sensor_id = {p} AND {} {NEWEST_FIRST} LIMIT 1",
        counts(Basis::ApprovedOnly)
    )
}

/// Removes a sensor's row when none of its calibrations counts any more
/// (after [`sensor_recompute`]): it is then no sensor anyone lists or
/// serves, though its calibrations stay, each with its state.
pub fn sensor_forget(p: &str) -> String {
    format!("DELETE FROM sensors WHERE sensor_id = {p} AND calibration_count = 0")
}

/// The last of the calibrations that replaced calibration `p` through
/// supersessions (`p` itself when none did), with its state: `id`, `state`.
pub fn chain_end_sql(p: &str) -> String {
    format!(
        "WITH RECURSIVE fwd(id, depth) AS ( \
           SELECT s.superseded_by, 1 FROM signatures s \
           WHERE s.calibration_id = {p} AND s.action = 'supersede' \
           UNION ALL \
           SELECT s.superseded_by, fwd.depth + 1 FROM signatures s JOIN fwd \
             ON s.calibration_id = fwd.id WHERE s.action = 'supersede' AND fwd.depth < 1000) \
         SELECT c.id, {} AS state FROM fwd JOIN calibrations c ON c.id = fwd.id \
         ORDER BY fwd.depth DESC LIMIT 1",
        crate::state_sql!()
    )
}

/// The columns of a nonconformity's row.
pub const NONCONFORMITY_COLUMNS: &str = "id, standard_id, found_at, last_known_good_at, \
     window_from, reason, recorded_at, token_id, role, holder";

/// The calibrations performed with the standard `$1` within `$2..=$3`
/// (`?1`… in SQLite), oldest first, with their states: the one query of
/// both engines but for how each reads a result's JSON (`standards`: a
/// condition on `c.result` naming the standard `$1`; `fitted_from`: one
/// that `c.result`'s `from_calibrations` names an id of the CTE `made`).
///
/// With them, the temperature models fitted from any of them: a model is
/// performed when its last constituent was and uses the union of their
/// standards, so a window that ends before the last constituent would
/// miss it, though its coefficients come from a calibration made in it. A
/// model is of its constituents' sensor and performed no earlier than any
/// of them, so it is looked for among those sensors' temperature models
/// from the window's start, by `calibrations_by_sensor_time` (a second
/// branch of a `UNION`: one condition `OR`ed into the first would scan
/// every calibration a second time).
pub fn made_with_sql(standards: &str, fitted_from: &str, p: [&str; 3]) -> String {
    let (from, to) = (p[1], p[2]);
    let columns = format!(
        "c.id, c.sensor_id, c.performed_at, {} AS state",
        state_sql!()
    );
    format!(
        "WITH made AS MATERIALIZED (SELECT c.id, c.sensor_id FROM calibrations c \
           WHERE c.performed_at >= {from} AND c.performed_at <= {to} AND {standards}) \
         SELECT {columns} FROM calibrations c WHERE c.id IN (SELECT id FROM made) \
         UNION \
         SELECT {columns} FROM calibrations c \
           JOIN (SELECT DISTINCT sensor_id FROM made) m ON c.sensor_id = m.sensor_id \
         WHERE c.performed_at >= {from} AND c.thermal IS NOT NULL AND {fitted_from} \
         ORDER BY performed_at, id"
    )
}

/// A temperature model of sensor `p[0]` that counts, performed no earlier
/// than `p[1]`, fitted from calibration `p[2]` (`fitted`: the engine's
/// condition that `c.result`'s `from_calibrations` names `p[2]`): what a
/// calibration that stops counting would leave standing on it. By
/// `calibrations_by_sensor_time` from the calibration's own time (a model
/// is performed when its last constituent was).
pub fn fitted_into_sql(fitted: &str, p: [&str; 3]) -> String {
    format!(
        "SELECT c.id FROM calibrations c WHERE c.sensor_id = {} AND c.performed_at >= {} \
         AND c.thermal IS NOT NULL AND {fitted} AND {} LIMIT 1",
        p[0],
        p[1],
        counts(Basis::NotRejected),
    )
}

/// Who submitted each calibration that calibration `p` replaces (directly,
/// or through earlier supersessions), nearest first: `submitted_by` — the
/// last row is the measurement's author
/// ([`crate::domain::review::Submitter::earlier`]). Each step by index
/// (`signatures_by_replacement`), each submitter by primary key: a join of
/// the steps with the calibrations let SQLite scan every calibration, an
/// approval taking 0.3 s at 100 000 (BENCHMARKS.md "A sensor's history").
pub fn earlier_submitters_sql(p: &str) -> String {
    format!(
        "WITH RECURSIVE back(id, depth) AS ( \
           SELECT s.calibration_id, 1 FROM signatures s \
           WHERE s.superseded_by = {p} AND s.action = 'supersede' \
           UNION ALL \
           SELECT s.calibration_id, back.depth + 1 FROM signatures s JOIN back \
             ON s.superseded_by = back.id WHERE s.action = 'supersede' AND back.depth < 1000) \
         SELECT (SELECT c.submitted_by FROM calibrations c WHERE c.id = back.id) AS submitted_by \
         FROM back ORDER BY back.depth"
    )
}

/// How a sensor's upsert merges into its stored row (`sensors`) what
/// `excluded` holds of its new calibrations (one, or several of a batch
/// folded into one row), in SQL that both engines run as it is — the one
/// statement of the rule:
///
/// * `calibration_count` adds up;
/// * `first_performed_at` is the least;
/// * the latest calibration is the greater by `(performed_at, id)`
///   ([`NEWEST_FIRST`]), and the latest verdict and due date are its;
/// * the assigned type is the new one when a write assigns one, and is
///   kept otherwise.
///
/// The sensor cache takes what the upsert answers ([`SENSOR_ROW`]) rather
/// than applying the rule again.
pub const SENSOR_MERGE: &str = "ON CONFLICT (sensor_id) DO UPDATE SET \
     calibration_count = sensors.calibration_count + excluded.calibration_count, \
     first_performed_at = CASE WHEN excluded.first_performed_at < sensors.first_performed_at \
       THEN excluded.first_performed_at ELSE sensors.first_performed_at END, \
     latest_calibration_id = CASE WHEN (excluded.latest_performed_at, excluded.latest_calibration_id) \
       > (sensors.latest_performed_at, sensors.latest_calibration_id) \
       THEN excluded.latest_calibration_id ELSE sensors.latest_calibration_id END, \
     latest_verdict = CASE WHEN (excluded.latest_performed_at, excluded.latest_calibration_id) \
       > (sensors.latest_performed_at, sensors.latest_calibration_id) \
       THEN excluded.latest_verdict ELSE sensors.latest_verdict END, \
     latest_due_at = CASE WHEN (excluded.latest_performed_at, excluded.latest_calibration_id) \
       > (sensors.latest_performed_at, sensors.latest_calibration_id) \
       THEN excluded.latest_due_at ELSE sensors.latest_due_at END, \
     latest_performed_at = CASE WHEN excluded.latest_performed_at > sensors.latest_performed_at \
       THEN excluded.latest_performed_at ELSE sensors.latest_performed_at END, \
     sensor_type = coalesce(excluded.sensor_type, sensors.sensor_type)";

/// What the sensors' upsert answers ([`SENSOR_MERGE`] then this): the
/// sensor's row as the write left it.
pub const SENSOR_ROW: &str = "RETURNING sensor_id, calibration_count, first_performed_at, \
     latest_performed_at, latest_calibration_id, sensor_type, latest_verdict, latest_due_at";

#[cfg(test)]
mod tests {
    use super::*;

    /// The SQL of [`counts`] refuses exactly the states [`State::counts`]
    /// refuses, on either basis: its `NOT IN` list names each of them and
    /// no other.
    #[test]
    fn counts_in_sql_is_the_rule() {
        for basis in [Basis::NotRejected, Basis::ApprovedOnly] {
            let sql = counts(basis);
            let list = sql
                .rsplit_once(" NOT IN (")
                .and_then(|(_, l)| l.strip_suffix(')'))
                .unwrap_or_else(|| panic!("{sql}"));
            let refused: Vec<&str> = list.split(", ").collect();
            for state in State::ALL {
                let quoted = format!("'{}'", state.as_str());
                assert_eq!(
                    refused.contains(&quoted.as_str()),
                    !state.counts(basis),
                    "{state:?} on {basis:?}: {sql}"
                );
            }
            assert_eq!(
                refused.len(),
                State::ALL.iter().filter(|s| !s.counts(basis)).count(),
                "{sql}"
            );
        }
    }

    /// [`State::ALL`] holds every state (a new one fails to compile here
    /// until it is added there too).
    #[test]
    fn every_state_is_listed() {
        for state in State::ALL {
            let i = match state {
                State::Submitted => 0,
                State::Approved => 1,
                State::Rejected => 2,
                State::Withdrawn => 3,
                State::Superseded => 4,
                State::UnderReview => 5,
            };
            assert_eq!(State::ALL[i], state);
        }
    }
}
