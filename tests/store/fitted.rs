//! A temperature model's constituents checked in the transaction that
//! stores it (`accelcal::store::fitted`): a calibration rejected,
//! withdrawn, superseded or held after the model's request read it, and
//! before the model was written, refuses the model; on PostgreSQL an act
//! that holds the calibration's row when the model's write starts makes it
//! wait and is seen once it commits.

use super::*;
use accelcal::domain::auth::Principal;
use accelcal::domain::review::{Act, Action, Refusal, supersession};
use accelcal::store::Signed;

fn reviewer() -> Principal {
    Principal {
        id: "0190aaaa000070008000000000000001".into(),
        role: Role::Reviewer,
        station_id: None,
        holder: Some("Rita".into()),
    }
}

fn act(action: Action) -> Act {
    Act {
        action,
        signer: reviewer(),
        at: t("2026-11-22T12:00:00Z"),
        comment: Some("chamber door left open".into()),
        superseded_by: None,
    }
}

/// A model of `sensor` performed at `at`, fitted from `from`.
fn model(sensor: &str, at: &str, from: &[Uuid]) -> NewCalibration {
    NewCalibration {
        fitted_from: from.to_vec(),
        ..calibration(sensor, at)
    }
}

/// The message of a refused model, which must be a conflict.
fn conflict(out: Result<Stored, StoreError>) -> String {
    match out {
        Err(StoreError::Conflict(why)) => why,
        other => panic!("the model was not refused as a conflict: {other:?}"),
    }
}

/// Part of the conformance suite: on every engine, a model is stored only
/// while each calibration it was fitted from makes one.
pub async fn constituents(s: &dyn Store) {
    let at = |day: u32| format!("2026-0{day}-01T00:00:00Z");
    let parts: Vec<NewCalibration> = (1..=5).map(|d| calibration("FIT", &at(d))).collect();
    for p in &parts {
        s.insert_calibration(p.clone(), None).await.unwrap();
    }
    let ids: Vec<Uuid> = parts.iter().map(|p| p.id).collect();

    // Rejected after the model's request read it.
    assert!(matches!(
        s.sign(ids[1], act(Action::Reject)).await.unwrap(),
        Signed::Done(..)
    ));
    let refused = model("FIT", &at(6), &ids[..2]);
    let why = conflict(s.insert_calibration(refused.clone(), None).await);
    assert!(
        why.contains(&ids[1].to_string()) && why.contains("rejected"),
        "{why}"
    );
    assert!(
        s.calibration_result(refused.id).await.unwrap().is_none(),
        "nothing of the refused model is stored"
    );
    assert_eq!(
        s.sensor("FIT".into(), now())
            .await
            .unwrap()
            .unwrap()
            .calibration_count,
        4,
        "the sensor's row is as the rejection left it"
    );

    // Withdrawn, and a calibration that is not stored at all.
    assert!(matches!(
        s.sign(ids[2], act(Action::Withdraw)).await.unwrap(),
        Signed::Done(..)
    ));
    let why = conflict(
        s.insert_calibration(model("FIT", &at(6), &[ids[0], ids[2]]), None)
            .await,
    );
    assert!(why.contains("withdrawn"), "{why}");
    let never = Uuid::now_v7();
    let why = conflict(
        s.insert_calibration(model("FIT", &at(6), &[ids[0], never]), None)
            .await,
    );
    assert!(why.contains(&format!("{never} is not stored")), "{why}");

    // From calibrations that count it is stored.
    let standing = model("FIT", &at(6), &[ids[0], ids[3]]);
    assert_eq!(
        s.insert_calibration(standing.clone(), None).await.unwrap(),
        Stored::New
    );
    assert!(s.calibration_result(standing.id).await.unwrap().is_some());

    // A correction fitted from the calibration it supersedes is refused,
    // and nothing of it is stored.
    let fixed = model("FIT", &at(6), &[ids[3], ids[4]]);
    let by = fixed.id;
    let out = s
        .supersede(
            ids[4],
            fixed,
            supersession("corrected".into(), reviewer(), now(), by),
        )
        .await
        .unwrap();
    assert_eq!(out, Signed::Refused(Refusal::FittedInto { model: by }));
    assert!(s.calibration_result(by).await.unwrap().is_none());
    assert!(s.signatures(ids[4]).await.unwrap().is_empty());
}

/// PostgreSQL: a reviewer's act holds the calibration's row (as `sign`
/// does, `FOR NO KEY UPDATE`) when the model's write starts; the write
/// waits for it, and once the act commits its rejection refuses the
/// model. Without the row's lock the model would read the state of before
/// the act and be stored.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_a_model_waits_for_an_act_on_what_it_was_fitted_from() {
    let db = pg::TestDb::create().await;
    let watch = db.client().await;
    let mut reviewer = db.client().await;
    let s = PostgresStore::open(&db.url).await.unwrap();
    let a = calibration("FIT-PG", "2026-01-01T00:00:00Z");
    let b = calibration("FIT-PG", "2026-02-01T00:00:00Z");
    for c in [&a, &b] {
        s.insert_calibration(c.clone(), None).await.unwrap();
    }

    let act = reviewer.transaction().await.unwrap();
    let me: i32 = act
        .query_one("SELECT pg_backend_pid()", &[])
        .await
        .unwrap()
        .get(0);
    act.execute(
        "SELECT id FROM calibrations WHERE id = $1 FOR NO KEY UPDATE",
        &[&b.id],
    )
    .await
    .unwrap();
    act.execute(
        "INSERT INTO signatures (calibration_id, seq, action, state, meaning, token_id, role, \
         holder, signed_at, comment, superseded_by) VALUES ($1, 1, 'reject', 'rejected', \
         'rejected', 'reviewer-token', 'reviewer', 'Rita', now(), 'door open', NULL)",
        &[&b.id],
    )
    .await
    .unwrap();

    let m = model("FIT-PG", "2026-03-01T00:00:00Z", &[a.id, b.id]);
    let store = s.clone();
    let write = tokio::spawn({
        let m = m.clone();
        async move { store.insert_calibration(m, None).await }
    });
    let waiting = "SELECT count(*) FROM pg_stat_activity WHERE $1 = ANY(pg_blocking_pids(pid))";
    let mut blocked = false;
    for _ in 0..500 {
        let n: i64 = watch.query_one(waiting, &[&me]).await.unwrap().get(0);
        if n > 0 {
            blocked = true;
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    assert!(blocked, "the model's write did not wait for the act's row");
    assert!(!write.is_finished());
    act.commit().await.unwrap();

    let why = conflict(write.await.unwrap());
    assert!(why.contains(&b.id.to_string()), "{why}");
    assert!(s.calibration_result(m.id).await.unwrap().is_none());
}
