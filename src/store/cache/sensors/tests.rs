//! The sensor cache's rules, each on its own: reads, drops, writes alone
//! and writes of one sensor in flight at once.

use super::*;
use crate::domain::timestamp::Timestamp;
use uuid::Uuid;

pub(crate) fn ts(s: &str) -> Timestamp {
    Timestamp::parse(s).unwrap()
}

fn summary(sensor: &str) -> SensorSummary {
    SensorSummary::for_test(sensor)
}

/// A calibration of `sensor` performed on `day` of January 2026.
fn newer(sensor: &str, id: u128, day: u8) -> CalibrationSummary {
    CalibrationSummary {
        performed_at: ts(&format!("2026-01-{day:02}T00:00:00Z")),
        ..CalibrationSummary::for_test(id, sensor, 0.5, 1.0)
    }
}

/// What the database answers when `c` is stored after
/// [`summary`]`(sensor)`'s one calibration (id 7, performed in 2025).
fn row(c: &CalibrationSummary) -> SensorRow {
    let before = summary(&c.sensor_id);
    let newest = (c.performed_at, c.id) > (before.latest.performed_at, before.latest.id);
    let latest = if newest { c } else { &before.latest };
    SensorRow {
        sensor_id: c.sensor_id.clone(),
        calibration_count: 2,
        first_performed_at: before.first_performed_at.min(c.performed_at),
        latest_performed_at: latest.performed_at,
        latest_calibration_id: latest.id,
        sensor_type: None,
        latest_verdict: latest.verdict,
        due_at: latest.due_at,
    }
}

fn stored(sensor: &str, id: u128, day: u8) -> Option<(CalibrationSummary, SensorRow)> {
    let c = newer(sensor, id, day);
    let r = row(&c);
    Some((c, r))
}

fn filled(c: &SensorCache, sensor: &str) {
    c.fill(c.begin().unwrap(), &summary(sensor));
    assert!(c.contains(sensor));
}

#[test]
fn a_read_that_raced_a_drop_does_not_fill() {
    let c = SensorCache::new(8, true);
    let epoch = c.begin().unwrap();
    c.invalidate("S");
    c.fill(epoch, &summary("S"));
    assert!(c.get("S").is_none(), "a fill from before the drop was kept");
    filled(&c, "S");
    c.invalidate("S");
    assert!(c.get("S").is_none());
}

/// Stripes: a drop of one sensor holds back another sensor's read only
/// when the two share a stripe.
#[test]
fn a_drop_holds_back_reads_of_its_stripe_only() {
    let c = SensorCache::new(1024, true);
    let apart = (0..)
        .map(|i| format!("T{i}"))
        .find(|t| c.stripe(t) != c.stripe("S"))
        .unwrap();
    let together = (0..)
        .map(|i| format!("U{i}"))
        .find(|u| c.stripe(u) == c.stripe("S"))
        .unwrap();
    let epoch = c.begin().unwrap();
    c.invalidate("S");
    c.fill(epoch, &summary(&apart));
    assert!(
        c.contains(&apart),
        "a drop of another stripe held a fill back"
    );
    c.fill(epoch, &summary(&together));
    assert!(!c.contains(&together), "a fill raced a drop of its stripe");
}

#[test]
fn a_cache_that_is_not_live_neither_answers_nor_fills() {
    let c = SensorCache::new(8, true);
    filled(&c, "S");
    c.reset(false);
    assert!(c.is_empty(), "reset empties");
    assert!(c.begin().is_none());
    assert!(c.get("S").is_none());
    c.reset(true);
    let epoch = c.begin().unwrap();
    c.reset(false);
    c.fill(epoch, &summary("S"));
    assert!(c.is_empty());
    // Nor does a write bring an entry back.
    c.reset(true);
    filled(&c, "S");
    let w = c.write("S");
    c.reset(false);
    w.settle(stored("S", 8, 2));
    assert!(c.is_empty());
}

#[test]
fn the_cache_holds_at_most_its_capacity() {
    let c = SensorCache::new(3, true);
    for i in 0..10 {
        c.fill(c.begin().unwrap(), &summary(&format!("S{i}")));
        assert!(c.len() <= 3);
    }
    assert_eq!(c.len(), 3);
    assert!(c.get("S9").is_some(), "the newest entry is kept");
    // Refilling a present sensor evicts nothing.
    c.fill(c.begin().unwrap(), &summary("S9"));
    assert_eq!(c.len(), 3);
}

/// A write alone puts in the row the database answered, with the
/// calibration it names as latest: the one written, or the one cached.
#[test]
fn a_write_alone_updates_its_sensor() {
    let c = SensorCache::new(8, true);
    filled(&c, "S");
    let w = c.write("S");
    let (written, r) = stored("S", 8, 2).unwrap();
    w.settle(Some((written.clone(), r.clone())));
    let s = c.get("S").expect("the written sensor stays cached");
    assert_eq!(s.latest, written);
    assert_eq!(s.calibration_count, 2);
    assert_eq!(s.latest_performed_at, written.performed_at);

    // An older calibration: the cached latest stays the latest.
    let older = CalibrationSummary {
        performed_at: ts("2020-01-01T00:00:00Z"),
        ..newer("S", 9, 1)
    };
    let mut r = row(&older);
    r.calibration_count = 3;
    r.latest_calibration_id = written.id;
    r.latest_performed_at = written.performed_at;
    c.write("S").settle(Some((older.clone(), r)));
    let s = c.get("S").expect("still cached");
    assert_eq!(
        (s.latest.id, s.first_performed_at),
        (written.id, older.performed_at)
    );

    // A sensor not cached is put in when the write is its latest.
    let (fresh, r) = stored("T", 10, 3).unwrap();
    c.write("T").settle(Some((fresh.clone(), r)));
    assert_eq!(c.get("T").unwrap().latest, fresh);
}

/// Every other end of a write drops the entry.
#[test]
fn a_write_that_did_not_store_or_raced_a_drop_drops_its_sensor() {
    let c = SensorCache::new(8, true);
    let stored = || stored("S", 8, 2);
    // Nothing stored, or the outcome unknown.
    filled(&c, "S");
    c.write("S").settle(None);
    assert!(!c.contains("S"));
    // Abandoned.
    filled(&c, "S");
    drop(c.write("S"));
    assert!(!c.contains("S"));
    // A latest that is neither the write's nor the cached one (a
    // newer calibration stored meanwhile by another process).
    filled(&c, "S");
    let (written, mut r) = stored().unwrap();
    r.latest_calibration_id = Uuid::from_u128(99);
    c.write("S").settle(Some((written, r)));
    assert!(!c.contains("S"));
    // Dropped meanwhile (another replica's notification).
    filled(&c, "S");
    let w = c.write("S");
    c.invalidate("S");
    c.fill(c.begin().unwrap(), &summary("S"));
    w.settle(stored());
    assert!(!c.contains("S"), "a write updated an entry after a drop");
}

/// `stored(sensor, id, day)` as the database answers it when `count`
/// calibrations of the sensor are stored, the latest being `latest`'s.
fn state(
    sensor: &str,
    id: u128,
    day: u8,
    count: u64,
    latest: &CalibrationSummary,
) -> (CalibrationSummary, SensorRow) {
    let (c, mut r) = stored(sensor, id, day).unwrap();
    r.calibration_count = count;
    r.latest_calibration_id = latest.id;
    r.latest_performed_at = latest.performed_at;
    (c, r)
}

/// Writes of one sensor in flight at once keep it cached, with the
/// latest state stored, whichever order they settle in: the row with the
/// greater calibration count is the later state.
#[test]
fn writes_in_flight_at_once_keep_the_latest_state() {
    for later_settles_first in [false, true] {
        let c = SensorCache::new(8, true);
        filled(&c, "S");
        let (a, b) = (c.write("S"), c.write("S"));
        let second = newer("S", 9, 3);
        let first = state("S", 8, 2, 2, &newer("S", 8, 2));
        let later = state("S", 9, 3, 3, &second);
        // A read in flight meanwhile fills nothing.
        let epoch = c.begin().unwrap();
        if later_settles_first {
            b.settle(Some(later));
            a.settle(Some(first));
        } else {
            a.settle(Some(first));
            assert_eq!(c.get("S").unwrap().calibration_count, 2);
            b.settle(Some(later));
        }
        c.fill(epoch, &summary("S"));
        let s = c.get("S").expect("the hot sensor stays cached");
        assert_eq!(
            (s.calibration_count, s.latest.id),
            (3, second.id),
            "later settled first: {later_settles_first}"
        );
    }
}

/// A write whose row names a latest it does not know (another write's
/// in its batch) leaves a floor: no write of an earlier state puts its
/// row after it, and the write of the same state that knows the latest
/// does.
#[test]
fn a_row_whose_latest_is_unknown_holds_back_earlier_states() {
    let c = SensorCache::new(8, true);
    filled(&c, "S");
    let (old, other, knower) = (c.write("S"), c.write("S"), c.write("S"));
    let latest = newer("S", 10, 4);
    // `other` (id 9) and `knower` (id 10) were stored in one batch: both
    // rows are the batch's, count 4, latest 10. `old` was stored before.
    other.settle(Some(state("S", 9, 3, 4, &latest)));
    assert!(!c.contains("S"), "a state without its latest was served");
    old.settle(Some(state("S", 8, 2, 2, &newer("S", 8, 2))));
    assert!(
        !c.contains("S"),
        "an earlier state was put after a later one"
    );
    knower.settle(Some(state("S", 10, 4, 4, &latest)));
    let s = c.get("S").expect("the write that knows the latest puts it");
    assert_eq!((s.calibration_count, s.latest.id), (4, latest.id));
    // Its sibling settling after it changes nothing.
    c.write("S").settle(Some(state("S", 9, 3, 4, &latest)));
    assert_eq!(c.get("S").unwrap().latest.id, latest.id);
}

/// A drop while writes are in flight (a review, another replica's
/// act, an unknown outcome, an eviction) keeps every one of them from
/// putting its row: the count orders states only between drops.
#[test]
fn a_drop_holds_back_every_write_in_flight() {
    let ends: [fn(&SensorCache); 3] = [
        |c| c.invalidate("S"),
        |c| c.write("S").settle(None),
        |c| drop(c.write("S")),
    ];
    for end in ends {
        let c = SensorCache::new(8, true);
        filled(&c, "S");
        let (a, b) = (c.write("S"), c.write("S"));
        end(&c);
        a.settle(Some(state("S", 8, 2, 2, &newer("S", 8, 2))));
        b.settle(Some(state("S", 9, 3, 3, &newer("S", 9, 3))));
        assert!(!c.contains("S"), "a write in flight put a row after a drop");
        // The next write alone puts its row again.
        c.write("S")
            .settle(Some(state("S", 10, 4, 4, &newer("S", 10, 4))));
        assert_eq!(c.get("S").unwrap().calibration_count, 4);
    }
    // Evicted while a write of it was in flight, with a floor held.
    let c = SensorCache::new(1, true);
    let other = (0..)
        .map(|i| format!("T{i}"))
        .find(|t| c.stripe(t) != c.stripe("S"))
        .unwrap();
    let (stale, floor) = (c.write("S"), c.write("S"));
    floor.settle(Some(state("S", 9, 3, 3, &newer("S", 10, 4))));
    assert_eq!(c.len(), 1, "the floor is held");
    filled(&c, &other);
    stale.settle(Some(state("S", 8, 2, 2, &newer("S", 8, 2))));
    assert!(!c.contains("S"), "an evicted floor let an earlier state in");
}

/// A read that may have seen the write's effect cannot fill while the
/// write is in flight, nor replace the write's row after it ended if it
/// began before.
#[test]
fn a_read_racing_a_write_does_not_fill() {
    let c = SensorCache::new(8, true);
    let w = c.write("S");
    let epoch = c.begin().unwrap();
    c.fill(epoch, &summary("S"));
    assert!(!c.contains("S"), "filled during a write");
    w.settle(stored("S", 8, 2));
    assert_eq!(
        c.get("S").unwrap().latest.id.as_u128(),
        8,
        "the write's row"
    );
    c.fill(epoch, &summary("S"));
    assert_eq!(
        c.get("S").unwrap().latest.id.as_u128(),
        8,
        "filled from before the write's end"
    );
}
