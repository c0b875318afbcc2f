//! Several handles or replicas on one database agree, and their caches
//! follow each other's writes and revocations.

use super::*;

/// Two handles on one database — two replicas — racing: of two claims of
/// one key exactly one wins; concurrent inserts for one sensor lose no
/// count and agree on the latest.
async fn two_handles(a: Arc<dyn Store>, b: Arc<dyn Store>) {
    let now = t("2026-11-22T00:00:00Z");
    for round in 0..20 {
        let k = key(&format!("race-{round}"), 1);
        let (x, y) = tokio::join!(
            a.claim_key(
                IdempotencyKey {
                    holder: Uuid::from_u128(1),
                    ..k.clone()
                },
                now,
                now.plus_seconds(90)
            ),
            b.claim_key(
                IdempotencyKey {
                    holder: Uuid::from_u128(2),
                    ..k.clone()
                },
                now,
                now.plus_seconds(90)
            ),
        );
        let mut got = [x.unwrap(), y.unwrap()];
        got.sort_by_key(|c| matches!(c, Claim::InFlight));
        assert_eq!(got, [Claim::Fresh, Claim::InFlight], "round {round}");
        // Both complete the key at once: one stores, the other names it.
        let (c1, c2) = (
            calibration(&format!("RACE-{round}"), "2026-01-01T00:00:00Z"),
            calibration(&format!("RACE-{round}"), "2026-01-02T00:00:00Z"),
        );
        let (r1, r2) = tokio::join!(
            a.insert_calibration(c1.clone(), Some(k.clone())),
            b.insert_calibration(c2.clone(), Some(k.clone())),
        );
        let (r1, r2) = (r1.unwrap(), r2.unwrap());
        let stored: Vec<Uuid> = [(&r1, c1.id), (&r2, c2.id)]
            .iter()
            .filter(|(r, _)| **r == Stored::New)
            .map(|(_, id)| *id)
            .collect();
        assert_eq!(stored.len(), 1, "round {round}: {r1:?} {r2:?}");
        for r in [r1, r2] {
            if let Stored::Existing(id) = r {
                assert_eq!(id, stored[0]);
            }
        }
        let sensor = a
            .sensor(format!("RACE-{round}"), now)
            .await
            .unwrap()
            .unwrap();
        assert_eq!((sensor.calibration_count, sensor.latest.id), (1, stored[0]));
    }
    // Forty inserts for one sensor through both handles: every one counted.
    let all: Vec<NewCalibration> = (0..40)
        .map(|i| calibration("HOT", &format!("2026-01-01T00:00:{i:02}Z")))
        .collect();
    let mut handles = Vec::new();
    for (i, c) in all.iter().cloned().enumerate() {
        let s = if i % 2 == 0 { a.clone() } else { b.clone() };
        handles.push(tokio::spawn(
            async move { s.insert_calibration(c, None).await },
        ));
    }
    for h in handles {
        assert_eq!(h.await.unwrap().unwrap(), Stored::New);
    }
    let hot = b.sensor("HOT".into(), now).await.unwrap().unwrap();
    assert_eq!(hot.calibration_count, 40);
    assert_eq!(
        hot.latest.id,
        all.last().unwrap().id,
        "the latest performed_at wins"
    );
    assert_eq!(hot.first_performed_at, t("2026-01-01T00:00:00Z"));

    // Withdrawals through one handle racing inserts through the other: the
    // sensor's row is what its surviving calibrations say, nothing lost.
    let reviewer = accelcal::domain::auth::Principal {
        id: "0190aaaa000070008000000000000002".into(),
        role: Role::Reviewer,
        station_id: None,
        holder: Some("Rita".into()),
    };
    let more: Vec<NewCalibration> = (0..20)
        .map(|i| calibration("HOT", &format!("2026-01-01T00:01:{i:02}Z")))
        .collect();
    let mut handles = Vec::new();
    for (i, c) in more.iter().cloned().enumerate() {
        let inserter = b.clone();
        handles.push(tokio::spawn(async move {
            inserter.insert_calibration(c, None).await.map(|_| ())
        }));
        // Withdraw half of the first forty, their latest among them.
        let withdrawn = all[(i * 2 + 3) % 40].id;
        let signer = a.clone();
        let act = accelcal::domain::review::Act {
            action: accelcal::domain::review::Action::Withdraw,
            signer: reviewer.clone(),
            at: now,
            comment: Some("race".into()),
            superseded_by: None,
        };
        handles.push(tokio::spawn(async move {
            match signer.sign(withdrawn, act).await? {
                accelcal::store::Signed::Done(..) => Ok(()),
                other => panic!("{other:?}"),
            }
        }));
    }
    for h in handles {
        h.await.unwrap().unwrap();
    }
    let truth = a
        .history(
            "HOT".into(),
            HistoryQuery {
                from: None,
                to: None,
                before: None,
                limit: 100,
            },
        )
        .await
        .unwrap();
    let counting: Vec<_> = truth
        .iter()
        .filter(|c| c.state == accelcal::domain::review::State::Submitted)
        .collect();
    assert_eq!(truth.len(), 60);
    assert_eq!(counting.len(), 40);
    for s in [&a, &b] {
        let hot = s.sensor("HOT".into(), now).await.unwrap().unwrap();
        assert_eq!(hot.calibration_count, 40);
        assert_eq!(hot.latest.id, counting[0].id, "newest first");
        assert_eq!(
            hot.first_performed_at,
            counting.last().unwrap().performed_at
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn sqlite_handles_agree() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two.db");
    let a = SqliteStore::open(&path).unwrap();
    let b = SqliteStore::open(&path).unwrap();
    two_handles(Arc::new(a), Arc::new(b)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replicas_agree() {
    let db = pg::TestDb::create().await;
    let (a, b) = tokio::join!(PostgresStore::open(&db.url), PostgresStore::open(&db.url));
    two_handles(Arc::new(a.unwrap()), Arc::new(b.unwrap())).await;
}

/// Replicas starting at once migrate once: the advisory lock.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replicas_starting_together_migrate_once() {
    let db = pg::TestDb::create().await;
    let opens: Vec<_> = (0..6)
        .map(|_| {
            let url = db.url.clone();
            tokio::spawn(async move { PostgresStore::open(&url).await.map(|_| ()) })
        })
        .collect();
    for o in opens {
        o.await.unwrap().unwrap();
    }
    let c = db.client().await;
    let versions: Vec<i32> = c
        .query(
            "SELECT version FROM accelcal_migrations ORDER BY version",
            &[],
        )
        .await
        .unwrap()
        .iter()
        .map(|r| r.get(0))
        .collect();
    assert_eq!(versions, (1..=18).collect::<Vec<_>>());
    // Version 18: a triad's model in the same column, the check admitting
    // either shape (tests/api/thermal_triad_stored.rs stores one).
    let check: String = c
        .query_one(
            "SELECT pg_get_constraintdef(oid) FROM pg_constraint \
             WHERE conname = 'a temperature model must be an object'",
            &[],
        )
        .await
        .unwrap()
        .get(0);
    for part in ["'coefficients'", "'b'", "'S'", "'set_points'"] {
        assert!(
            check.contains(part),
            "version 18's check lacks {part}: {check}"
        );
    }
    // Version 17: a calibration's temperature model, checked an object.
    let thermal = c
        .query(
            "SELECT 1 FROM information_schema.columns \
             WHERE table_name = 'calibrations' AND column_name = 'thermal'",
            &[],
        )
        .await
        .unwrap();
    assert_eq!(thermal.len(), 1, "version 17's column");
    // Version 16: webhook endpoints, their log, the statuses announced.
    let tables = c
        .query(
            "SELECT 1 FROM pg_tables WHERE tablename IN \
             ('webhooks', 'webhook_deliveries', 'status_announcements')",
            &[],
        )
        .await
        .unwrap();
    assert_eq!(tables.len(), 3, "version 16's tables");
    // Version 15: pending audit entries, never changed.
    let pending = c
        .query(
            "SELECT 1 FROM pg_trigger WHERE tgname = 'audit_pending_kept' AND NOT tgisinternal",
            &[],
        )
        .await
        .unwrap();
    assert_eq!(pending.len(), 1, "version 15's table and trigger");
    // Version 14: the signatures naming a replacement, indexed.
    let index = c
        .query(
            "SELECT 1 FROM pg_indexes WHERE indexname = 'signatures_by_replacement'",
            &[],
        )
        .await
        .unwrap();
    assert_eq!(index.len(), 1);
    // Version 4: tokens' changes are notified.
    let triggers = c
        .query(
            "SELECT 1 FROM pg_trigger WHERE tgname = 'tokens_notify' AND NOT tgisinternal",
            &[],
        )
        .await
        .unwrap();
    assert_eq!(triggers.len(), 1, "version 4's trigger");
    // Version 3: result documents and submissions compressed with lz4 (this
    // server, Debian's, is built with it).
    let compression: Vec<(String, i8)> = c
        .query(
            "SELECT attname::text, attcompression FROM pg_attribute \
             WHERE attrelid = 'calibrations'::regclass AND attname IN ('result', 'submission') \
             ORDER BY attname",
            &[],
        )
        .await
        .unwrap()
        .iter()
        .map(|r| (r.get(0), r.get(1)))
        .collect();
    assert_eq!(
        compression,
        [
            ("result".to_owned(), b'l' as i8),
            ("submission".to_owned(), b'l' as i8)
        ]
    );
}

/// Two replicas, each with its token cache: a token one revokes stops
/// authenticating at the other once the notification arrives (the window
/// is printed), at once at the one that revoked it; while the other's
/// listener is gone it reads the database.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replica_token_caches_follow_revocations() {
    let db = pg::TestDb::create().await;
    let replica = || async {
        let s = PostgresStore::cached(&db.url).await.unwrap();
        let tokens = s.cache().tokens().clone();
        until(
            || tokens.is_live() && s.cache().sensors().is_live(),
            "the listener to connect",
        )
        .await;
        (s, tokens)
    };
    let (a, _) = replica().await;
    let (b, b_tokens) = replica().await;
    let token = |n: u128| TokenRecord {
        id: Uuid::from_u128(n),
        secret_hash: vec![7; 32],
        role: Role::Reader,
        station_id: None,
        label: None,
        holder: None,
        created_at: t("2026-11-22T00:00:00Z"),
        revoked_at: None,
    };
    for n in [1, 2] {
        a.insert_token(token(n), admin()).await.unwrap();
        assert_eq!(b.token(Uuid::from_u128(n)).await.unwrap(), Some(token(n)));
        assert!(
            b_tokens.contains(Uuid::from_u128(n)),
            "b's read filled its cache"
        );
    }
    assert_eq!(b.token(Uuid::from_u128(3)).await.unwrap(), None);
    assert!(
        !b_tokens.contains(Uuid::from_u128(3)),
        "an unknown id is not cached"
    );

    let at = t("2026-11-22T01:00:00Z");
    assert!(
        a.revoke_token(Uuid::from_u128(1), at, admin())
            .await
            .unwrap()
    );
    assert_eq!(
        a.token(Uuid::from_u128(1))
            .await
            .unwrap()
            .unwrap()
            .revoked_at,
        Some(at),
        "the replica that revoked it serves the revocation at once"
    );
    let started = std::time::Instant::now();
    loop {
        let seen = b.token(Uuid::from_u128(1)).await.unwrap().unwrap();
        if seen.revoked_at == Some(at) {
            eprintln!(
                "replica b served a's revocation {:?} after it returned",
                started.elapsed()
            );
            break;
        }
        assert!(
            started.elapsed() < std::time::Duration::from_secs(10),
            "replica b still serves the token as valid after 10 s"
        );
        tokio::time::sleep(std::time::Duration::from_millis(1)).await;
    }
    assert!(
        b_tokens.contains(Uuid::from_u128(2)),
        "the other token stays cached"
    );

    // b's listener is cut off: b reads the database until it is back.
    cut_listeners(&db).await;
    until(|| !b_tokens.is_live(), "b to notice").await;
    assert!(
        b_tokens.is_empty(),
        "a cache without its listener is emptied"
    );
    assert!(
        a.revoke_token(Uuid::from_u128(2), at, admin())
            .await
            .unwrap()
    );
    assert_eq!(
        b.token(Uuid::from_u128(2))
            .await
            .unwrap()
            .unwrap()
            .revoked_at,
        Some(at),
        "a replica without its listener read a stale token"
    );
    a.close().await;
    b.close().await;
}

/// Two replicas, each with its cache: what one stores, the other serves
/// once the notification arrives — never the replaced calibration for
/// longer — and while its listener is gone it reads the database instead.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn postgres_replica_caches_follow_each_others_writes() {
    let db = pg::TestDb::create().await;
    let (a, _) = cached_replica(&db.url).await;
    let (b, b_cache) = cached_replica(&db.url).await;
    let now = t("2026-11-22T00:00:00Z");
    let first = calibration("SHARED", "2026-01-01T00:00:00Z");
    a.insert_calibration(first.clone(), None).await.unwrap();
    // b's first reads may race the notification of a's insert, which
    // forbids them to fill; one after it does.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while b_cache.is_empty() {
        let seen = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
        assert_eq!(seen.latest.id, first.id);
        assert!(
            std::time::Instant::now() < deadline,
            "b's reads never filled its cache"
        );
    }
    for (i, day) in ["02", "03", "04"].into_iter().enumerate() {
        let newer = calibration("SHARED", &format!("2026-01-{day}T00:00:00Z"));
        a.insert_calibration(newer.clone(), None).await.unwrap();
        let started = std::time::Instant::now();
        loop {
            let s = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
            if s.latest.id == newer.id {
                assert_eq!(s.calibration_count, i as u64 + 2);
                eprintln!(
                    "replica b served a's write {:?} after a's insert returned",
                    started.elapsed()
                );
                break;
            }
            assert!(
                started.elapsed() < std::time::Duration::from_secs(10),
                "replica b still serves {} after 10 s",
                s.latest.id
            );
            tokio::time::sleep(std::time::Duration::from_millis(1)).await;
        }
        // And a's own write is seen by a at once, from its cache or not.
        let own = a.sensor("SHARED".into(), now).await.unwrap().unwrap();
        assert_eq!(own.latest.id, newer.id);
    }
    // b's listener is cut off: b bypasses its cache until it is back.
    assert_eq!(
        cut_listeners(&db).await,
        2,
        "both replicas' listeners were connected"
    );
    until(|| !b_cache.is_live(), "b to notice").await;
    let during = calibration("SHARED", "2026-02-01T00:00:00Z");
    a.insert_calibration(during.clone(), None).await.unwrap();
    let s = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
    assert_eq!(
        s.latest.id, during.id,
        "a replica without its listener read a stale entry"
    );
    until(|| b_cache.is_live(), "b's listener to reconnect").await;
    let s = b.sensor("SHARED".into(), now).await.unwrap().unwrap();
    assert_eq!(s.latest.id, during.id);
    a.close().await;
    b.close().await;
}
