//! Tests of [`super`] on a real PostgreSQL.

use super::history::{fetched, history_page};
use super::*;
use accelcal_testkit::pg::TestDb;
use tokio_postgres::SimpleQueryMessage;

/// Rows of `calibrations` for `sensor` (an SQL expression of `g`),
/// `g` in `1..=n`, performed one second apart from `start`.
fn rows(n: usize, sensor: &str, start: &str) -> String {
    format!(
        "INSERT INTO calibrations (id, sensor_id, performed_at, received_at, unit, model, \
         runs, coefficients, std_errors, result, submission, content_type, submitted_by) \
         SELECT gen_random_uuid(), {sensor}, {start} + g * interval '1 s', now(), 'mA', \
         '[\"k0\"]', 4, '{{\"k0\": 1}}', '{{\"k0\": 1}}', repeat('x', 2000), '\\x00', \
         'application/json', 't' FROM generate_series(1, {n}) g;"
    )
}

/// `EXPLAIN (FORMAT JSON)` of `statement`, as text.
async fn explain(c: &tokio_postgres::Client, statement: &str) -> String {
    c.simple_query(&format!("EXPLAIN (FORMAT JSON) {statement}"))
        .await
        .unwrap()
        .into_iter()
        .find_map(|m| match m {
            SimpleQueryMessage::Row(r) => r.get(0).map(str::to_owned),
            _ => None,
        })
        .unwrap()
}

/// The node under the plan's `Limit`, from `EXPLAIN (FORMAT JSON)`.
fn under_limit(explained: &str) -> serde_json::Value {
    let plan: serde_json::Value = serde_json::from_str(explained).unwrap();
    let top = &plan[0]["Plan"];
    assert_eq!(top["Node Type"], "Limit", "{plan:#}");
    top["Plans"][0].clone()
}

/// A sensor's latest calibration that counts, before a time or of all,
/// is found by walking its index backward from the bound — even by a
/// generic plan made on statistics taken while the table was small
/// (1 000 sensors of 5 calibrations), once one sensor has 13 400. With
/// the state condition written `IN (…)`, PostgreSQL 15 chose a bitmap
/// scan of the sensor's whole history and a sort here (25–33 ms a read,
/// and 138–158 ms under load: [`counts`]).
#[tokio::test]
async fn previous_walks_the_index_on_stale_statistics() {
    let db = TestDb::create().await;
    PostgresStore::open(&db.url).await.unwrap();
    let c = db.client().await;
    c.batch_execute(&format!(
        "ALTER TABLE calibrations SET (autovacuum_enabled = false); {} \
         ANALYZE calibrations; ANALYZE signatures; {} \
         SET plan_cache_mode = force_generic_plan;",
        rows(5_000, "'F' || (g % 1000)", "now() - interval '1 day'"),
        rows(13_400, "'HOT'", "now()"),
    ))
    .await
    .unwrap();
    for (i, basis) in [Basis::NotRejected, Basis::ApprovedOnly]
        .into_iter()
        .enumerate()
    {
        for before in [true, false] {
            let name = format!("p{i}{}", u8::from(before));
            c.batch_execute(&format!(
                "PREPARE {name} AS {}",
                previous_sql(basis, before)
            ))
            .await
            .unwrap();
            let args = if before {
                "'HOT', now() + interval '1 day'"
            } else {
                "'HOT'"
            };
            let explained = explain(&c, &format!("EXECUTE {name}({args})")).await;
            let scan = under_limit(&explained);
            assert_eq!(
                scan["Node Type"], "Index Scan",
                "{basis:?} {before}: {scan:#}"
            );
            assert_eq!(scan["Scan Direction"], "Backward", "{scan:#}");
            assert_eq!(
                scan["Index Name"], "calibrations_by_sensor_time",
                "{scan:#}"
            );
        }
    }
}

/// A history page's statement is planned once per connection, however
/// long the sensor's history: after PostgreSQL's five custom plans, the
/// generic plan (its index condition on `$1`, not on the sensor's name)
/// is kept for every combination of conditions. Written with `$n IS NULL
/// OR …` and `LIMIT $n`, the same page was planned anew at every
/// execution on a sensor of 13 400 calibrations ([`history_page`]).
#[tokio::test]
async fn a_history_page_keeps_its_generic_plan() {
    let db = TestDb::create().await;
    PostgresStore::open(&db.url).await.unwrap();
    let c = db.client().await;
    c.batch_execute(&format!(
        "ALTER TABLE calibrations SET (autovacuum_enabled = false); {} \
         ANALYZE calibrations; ANALYZE signatures;",
        rows(13_400, "'HOT'", "now()"),
    ))
    .await
    .unwrap();
    let at = "now() + interval '1 hour'";
    let newest: Uuid = c
        .query_one(
            "SELECT id FROM calibrations ORDER BY performed_at DESC LIMIT 1",
            &[],
        )
        .await
        .unwrap()
        .get(0);
    let before = format!("'{newest}'");
    for (k, (from, to, cursor)) in [
        (false, false, false),
        (true, false, false),
        (false, true, true),
        (true, true, true),
    ]
    .into_iter()
    .enumerate()
    {
        let q = HistoryQuery {
            from: from.then(Timestamp::now),
            to: to.then(Timestamp::now),
            before: cursor.then(Uuid::nil),
            limit: 51,
        };
        let select = concat!("SELECT c.id, ", crate::state_sql!(), " AS state");
        let sql = format!("{select} {}", history_page(&q));
        assert!(sql.ends_with("LIMIT 64"), "{sql}");
        let mut args = vec!["'HOT'".to_owned()];
        if from {
            args.push("now() - interval '1 day'".into());
        }
        if to {
            args.push(at.into());
        }
        if cursor {
            args.push(before.clone());
        }
        let args = args.join(", ");
        c.batch_execute(&format!("PREPARE h{k} AS {sql}"))
            .await
            .unwrap();
        for _ in 0..6 {
            c.batch_execute(&format!("EXECUTE h{k}({args})"))
                .await
                .unwrap();
        }
        let explained = explain(&c, &format!("EXECUTE h{k}({args})")).await;
        // The walk of the sensor's index, beside the cursor's look-up.
        let plan: serde_json::Value = serde_json::from_str(&explained).unwrap();
        let scan = plan[0]["Plan"]["Plans"]
            .as_array()
            .and_then(|p| p.iter().find(|n| n["Parent Relationship"] == "Outer"))
            .cloned()
            .unwrap_or_else(|| panic!("{k}: {plan:#}"));
        assert_eq!(plan[0]["Plan"]["Node Type"], "Limit", "{plan:#}");
        assert_eq!(scan["Scan Direction"], "Backward", "{k}: {scan:#}");
        assert_eq!(
            scan["Index Name"], "calibrations_by_sensor_time",
            "{k}: {scan:#}"
        );
        let cond = scan["Index Cond"].as_str().unwrap_or_default();
        assert!(cond.contains("$1"), "{k}: a custom plan: {scan:#}");
    }
}

#[test]
fn a_history_page_fetches_a_power_of_two() {
    assert_eq!(
        [1, 2, 3, 20, 21, 51, 500, 501].map(fetched),
        [1, 2, 4, 32, 32, 64, 512, 512]
    );
}
