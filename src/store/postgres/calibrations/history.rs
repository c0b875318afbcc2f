//! A page of a sensor's history on PostgreSQL: the statement for the
//! conditions a query has, and its rows.

use deadpool_postgres::Object;

use super::map;
use crate::store::{HistoryQuery, NEWEST_FIRST, StoreError};

/// A page of a sensor's history after the selected columns: newest first,
/// within `from..=to`, before the calibration `before`, at most `limit`.
///
/// The statement names only the conditions the query has, and its `LIMIT`
/// is a literal: `limit` rounded up to a power of two (at most ten sizes
/// up to the largest page), the surplus dropped by [`page`]. Written as
/// one statement with `$n IS NULL OR …` conditions and `LIMIT $n`, its
/// generic plan was estimated on a tenth of the sensor's rows against a
/// custom plan's page, so once a sensor's history grew PostgreSQL planned
/// it anew at every execution — 0.05 ms of planning for a 0.03 ms walk of
/// the index, half of the database's CPU per history page
/// (BENCHMARKS.md "A faster machine, where PostgreSQL's submission goes,
/// and a history page planned once"). With neither, the generic plan costs
/// what a custom one does and is kept: at most eighty statements per
/// connection, each planned once.
pub(super) fn history_page(q: &HistoryQuery) -> String {
    // Each condition given, around its parameter: the next after `$1`.
    let conditions = [
        (q.from.is_some(), "c.performed_at >= ", ""),
        (q.to.is_some(), "c.performed_at <= ", ""),
        (
            q.before.is_some(),
            "(c.performed_at, c.id) < (SELECT b.performed_at, b.id FROM calibrations b WHERE b.id = ",
            ")",
        ),
    ];
    let mut sql = String::from("FROM calibrations c WHERE c.sensor_id = $1");
    let given = conditions.iter().filter(|(given, _, _)| *given);
    for (k, (_, head, tail)) in given.enumerate() {
        sql.push_str(&format!(" AND {head}${}{tail}", k + 2));
    }
    format!("{sql} {NEWEST_FIRST} LIMIT {}", fetched(q.limit))
}

/// How many rows a history page's statement fetches for a page of `limit`:
/// the next power of two.
pub(super) fn fetched(limit: usize) -> usize {
    limit.max(1).next_power_of_two()
}

pub(super) async fn page(
    client: &Object,
    select: &str,
    sensor_id: &str,
    q: &HistoryQuery,
) -> Result<Vec<tokio_postgres::Row>, StoreError> {
    let stmt = client
        .prepare_cached(&format!("{select} {}", history_page(q)))
        .await
        .map_err(map)?;
    let (from, to) = (q.from.map(|t| t.datetime()), q.to.map(|t| t.datetime()));
    let mut params: Vec<&(dyn tokio_postgres::types::ToSql + Sync)> = vec![&sensor_id];
    if let Some(from) = &from {
        params.push(from);
    }
    if let Some(to) = &to {
        params.push(to);
    }
    if let Some(before) = &q.before {
        params.push(before);
    }
    let mut rows = client.query(&stmt, &params).await.map_err(map)?;
    rows.truncate(q.limit);
    Ok(rows)
}
