//! The sensor cache: writes through this process keep their sensor cached.

use super::*;
use accelcal::domain::review::Basis;
use accelcal::store::Precondition;

/// A replica behind its sensor cache and listener, as `store::open` builds
/// it, with the cache at hand; waits until the listener is connected.
pub(crate) async fn cached_replica(url: &str) -> (Arc<dyn Store>, Arc<SensorCache>) {
    let store = PostgresStore::cached(url).await.unwrap();
    let cache = store.cache().sensors().clone();
    until(|| cache.is_live(), "the listener to connect").await;
    (Arc::new(store), cache)
}

/// Ends every cache listener's connection to `db`; answers how many.
pub(crate) async fn cut_listeners(db: &pg::TestDb) -> u64 {
    db.client()
        .await
        .execute(
            "SELECT pg_terminate_backend(pid) FROM pg_stat_activity \
             WHERE datname = $1 AND application_name = $2",
            &[
                &db.name,
                &accelcal::store::postgres::listen::APPLICATION_NAME,
            ],
        )
        .await
        .unwrap()
}

/// A station's writes through the cache, each followed by the reads it
/// serves: after every write the sensor stays cached (the write brought its
/// entry up to date instead of dropping it) and what the cache serves is,
/// field for field, what the engine reads from the database without it
/// (`reference`). The writes cover each rule of the sensor's summary: a
/// newer, an older and two equal `performed_at` (the later id wins the
/// tie, the earlier does not), a type assigned, a type in force but not
/// assigned, a failed verdict. `settle` is how long a notification of the
/// write has to arrive and (wrongly) drop the entry.
async fn writes_keep_their_sensor_cached(
    store: &dyn Store,
    reference: &dyn Store,
    cache: &SensorCache,
    settle: std::time::Duration,
) {
    store
        .put_sensor_type(sensor_type("NAV", 365), admin(), Precondition::Any)
        .await
        .unwrap();
    let sensor = "KEEP";
    let read = |s: &'static str| async move {
        let at = t("2026-11-22T00:00:00Z");
        let cached = store.sensor(s.into(), at).await.unwrap().unwrap();
        let truth = reference.sensor(s.into(), at).await.unwrap().unwrap();
        (cached, truth)
    };
    store
        .insert_calibration(calibration(sensor, "2026-03-01T00:00:00Z"), None)
        .await
        .unwrap();
    let (cached, truth) = read(sensor).await;
    assert_eq!(cached, truth);
    assert!(cache.contains(sensor), "the read filled the cache");

    let typed = |at: &str, verdict: Verdict, assigns: bool| NewCalibration {
        sensor_type: Some("NAV".into()),
        assigns_type: assigns,
        verdict: Some(verdict),
        due_at: Some(t(at)),
        ..calibration(sensor, at)
    };
    let tie_low = NewCalibration {
        id: Uuid::from_u128(1),
        ..calibration(sensor, "2026-04-01T00:00:00Z")
    };
    let writes = [
        (
            "newer, typed, assigning its type",
            typed("2026-04-01T00:00:00Z", Verdict::Pass, true),
        ),
        ("older", calibration(sensor, "2026-01-01T00:00:00Z")),
        (
            "a tie, the later id",
            calibration(sensor, "2026-04-01T00:00:00Z"),
        ),
        ("a tie, an earlier id", tie_low),
        (
            "newer, type in force but not assigned, failed",
            typed("2026-05-01T00:00:00Z", Verdict::Fail, false),
        ),
        (
            "newer, untyped",
            calibration(sensor, "2026-06-01T00:00:00Z"),
        ),
    ];
    let mut count = 1;
    for (what, w) in writes {
        store.insert_calibration(w, None).await.unwrap();
        count += 1;
        tokio::time::sleep(settle).await;
        assert!(
            cache.contains(sensor),
            "{what}: the write dropped its sensor"
        );
        let (cached, truth) = read(sensor).await;
        assert_eq!(
            cached, truth,
            "{what}: the cache serves what the database does not"
        );
        assert_eq!(cached.calibration_count, count, "{what}");
        let before = t("2027-01-01T00:00:00Z");
        assert_eq!(
            store
                .previous_calibration(sensor.into(), before, Basis::NotRejected)
                .await
                .unwrap(),
            reference
                .previous_calibration(sensor.into(), before, Basis::NotRejected)
                .await
                .unwrap(),
            "{what}"
        );
    }
    let (last, _) = read(sensor).await;
    assert_eq!(
        last.sensor_type.as_deref(),
        Some("NAV"),
        "assigned once, kept"
    );
    assert_eq!(last.latest.performed_at, t("2026-06-01T00:00:00Z"));
    assert_eq!(last.latest_verdict, None);
}

#[tokio::test]
async fn sqlite_writes_keep_their_sensor_cached() {
    let dir = tempfile::tempdir().unwrap();
    let inner = SqliteStore::open(dir.path().join("kept.db")).unwrap();
    let store = inner.clone().cached();
    let cache = store.cache().sensors().clone();
    writes_keep_their_sensor_cached(&store, &inner, &cache, std::time::Duration::ZERO).await;
}

/// The same behind PostgreSQL's listener: the replica's own notifications
/// are echoes and drop nothing; another replica's write still drops the
/// entry.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_writes_keep_their_sensor_cached() {
    let db = pg::TestDb::create().await;
    let (store, cache) = cached_replica(&db.url).await;
    let reference = PostgresStore::open(&db.url).await.unwrap();
    let settle = std::time::Duration::from_millis(100);
    writes_keep_their_sensor_cached(&*store, &reference, &cache, settle).await;
    let (other, _) = cached_replica(&db.url).await;
    other
        .insert_calibration(calibration("KEEP", "2026-07-01T00:00:00Z"), None)
        .await
        .unwrap();
    until(
        || !cache.contains("KEEP"),
        "another replica's write to drop the entry",
    )
    .await;
    store.close().await;
    other.close().await;
}

/// Many writes of one sensor at once (a hot sensor: stations submitting
/// faster than they are stored), in bursts, their `performed_at` out of
/// order: whichever order they settle in, what the cache serves after each
/// burst is what the database holds, and the next write alone leaves the
/// sensor cached.
async fn a_hot_sensor_is_served_as_stored(
    store: Arc<dyn Store>,
    reference: &dyn Store,
    cache: &SensorCache,
) {
    let sensor = "HOT";
    let at = t("2027-06-01T00:00:00Z");
    let mut count = 0;
    for burst in 0..16u32 {
        let writes: Vec<_> = (0..32u32)
            .map(|i| {
                let store = store.clone();
                // Days scattered over the burst's month, so that writes queued
                // later are often older than writes queued before them.
                let day = 1 + (i * 7 + burst) % 28;
                let performed = format!("2026-{:02}-{day:02}T{:02}:00:00Z", burst % 12 + 1, i % 24);
                tokio::spawn(async move {
                    store
                        .insert_calibration(calibration(sensor, &performed), None)
                        .await
                        .unwrap()
                })
            })
            .collect();
        for w in writes {
            w.await.unwrap();
        }
        count += 32;
        let cached = store.sensor(sensor.into(), at).await.unwrap().unwrap();
        let truth = reference.sensor(sensor.into(), at).await.unwrap().unwrap();
        assert_eq!(
            cached, truth,
            "burst {burst}: the cache serves a stale sensor"
        );
        assert_eq!(cached.calibration_count, count, "burst {burst}");
    }
    store
        .insert_calibration(calibration(sensor, "2026-12-31T00:00:00Z"), None)
        .await
        .unwrap();
    assert!(
        cache.contains(sensor),
        "a write alone after the bursts dropped its sensor"
    );
    let cached = store.sensor(sensor.into(), at).await.unwrap().unwrap();
    assert_eq!(
        cached,
        reference.sensor(sensor.into(), at).await.unwrap().unwrap()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sqlite_a_hot_sensor_is_served_as_stored() {
    let dir = tempfile::tempdir().unwrap();
    let inner = SqliteStore::open(dir.path().join("hot.db")).unwrap();
    let store = inner.clone().cached();
    let cache = store.cache().sensors().clone();
    a_hot_sensor_is_served_as_stored(Arc::new(store), &inner, &cache).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_a_hot_sensor_is_served_as_stored() {
    let db = pg::TestDb::create().await;
    let (store, cache) = cached_replica(&db.url).await;
    let reference = PostgresStore::open(&db.url).await.unwrap();
    a_hot_sensor_is_served_as_stored(store.clone(), &reference, &cache).await;
    store.close().await;
}
