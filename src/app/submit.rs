//! Submitting a calibration: assessed by its kind ([`Kind`]) and stored durably — at most once per idempotency key:
//! a retry of a stored submission is answered with what it stored, and a
//! key in use by a request still running, or used with another input, is
//! refused.

use std::sync::Arc;

use bytes::Bytes;
use uuid::Uuid;

use super::{Error, Kind, Lab, Upload};
use crate::domain::auth::Principal;
use crate::domain::timestamp::Timestamp;
use crate::store::{Claim, IdempotencyKey, NewCalibration, Store, StoreError, Stored};

/// A submission ready to be answered (and stored).
pub struct Assessed {
    /// The sensor.
    pub sensor_id: String,
    /// The result document, rendered once.
    pub result: Bytes,
    /// What to store, when the caller asked for a stored calibration.
    pub record: Option<NewCalibration>,
}

/// A stored calibration, as its submitter is answered.
#[derive(Debug)]
pub struct Submitted {
    /// Its id.
    pub id: Uuid,
    /// Its result document, as stored.
    pub result: Bytes,
    /// Whether it was stored before, by an earlier request with the same
    /// idempotency key (or one that raced this one).
    pub replayed: bool,
}

/// Holds a claimed idempotency key; releases it if the act ends (an error,
/// or the caller went away) without storing a calibration.
struct KeyGuard {
    store: Arc<dyn Store>,
    key: Option<IdempotencyKey>,
}

impl KeyGuard {
    fn done(mut self) {
        self.key = None;
    }

    /// Releases the key before the act answers its error, so that the
    /// client's corrected retry with the same key finds it free (released
    /// on drop, by a task of its own, the retry could come first and be
    /// refused as a key reused with another body).
    async fn release(mut self) {
        if let Some(k) = self.key.take()
            && let Err(e) = self.store.release_key(k).await
        {
            tracing::warn!(error = %e.chain(), "could not release an idempotency key; its lease will expire");
        }
    }
}

/// `result` answered after `guard`'s key is released, if it is an error.
async fn or_release<T>(result: Result<T, Error>, guard: &mut Option<KeyGuard>) -> Result<T, Error> {
    if result.is_err()
        && let Some(g) = guard.take()
    {
        g.release().await;
    }
    result
}

impl Drop for KeyGuard {
    fn drop(&mut self) {
        if let Some(k) = self.key.take()
            && let Ok(rt) = tokio::runtime::Handle::try_current()
        {
            let store = self.store.clone();
            rt.spawn(async move {
                if let Err(e) = store.release_key(k).await {
                    tracing::warn!(error = %e.chain(), "could not release an idempotency key; its lease will expire");
                }
            });
        }
    }
}

/// How long a key's lease outlasts its act's deadline: time for the act's
/// last write to land. A lease that expires anyway (a crashed replica's)
/// is taken over; the key's completion is guarded in the store, so even
/// then one key stores one calibration.
const LEASE_MARGIN_SECONDS: i64 = 5;

/// Claims `key`: its guard, or the answer already due (a retry of a stored
/// submission).
async fn claim(lab: &Lab, key: &IdempotencyKey) -> Result<Result<KeyGuard, Submitted>, Error> {
    let now = Timestamp::now();
    let lease = now.plus_seconds(lab.deadline.as_secs() as i64 + LEASE_MARGIN_SECONDS);
    match lab.store.claim_key(key.clone(), now, lease).await? {
        Claim::Fresh => Ok(Ok(KeyGuard {
            store: lab.store.clone(),
            key: Some(key.clone()),
        })),
        Claim::Done(id) => Ok(Err(replay(lab, id).await?)),
        Claim::InFlight => Err(Error::InFlight),
        Claim::Mismatch => Err(Error::KeyReused),
    }
}

/// The calibration a key already stored.
async fn replay(lab: &Lab, id: Uuid) -> Result<Submitted, Error> {
    let result = lab.store.calibration_result(id).await?.ok_or_else(|| {
        StoreError::corrupt("idempotency key", format!("names missing calibration {id}"))
    })?;
    Ok(Submitted {
        id,
        result,
        replayed: true,
    })
}

/// Stores `rec` under `key`, releasing the key's guard once stored — or,
/// when a concurrent request with the same key stored first, answers that
/// one.
async fn store(
    lab: &Lab,
    rec: NewCalibration,
    key: Option<IdempotencyKey>,
    mut guard: Option<KeyGuard>,
) -> Result<Submitted, Error> {
    let (id, sensor_id, verdict, result) = (
        rec.id,
        rec.sensor_id.clone(),
        rec.verdict,
        rec.result.clone(),
    );
    let kind = match (&rec.triad, &rec.thermal, &rec.thermal_triad) {
        (Some(_), _, Some(_)) => "thermal-triad",
        (Some(_), _, None) => "triad",
        (None, Some(_), _) => "thermal",
        (None, None, _) => "single-axis",
    };
    let stored = lab
        .store
        .insert_calibration(rec, key)
        .await
        .map_err(Error::from);
    let stored = or_release(stored, &mut guard).await?;
    if let Some(g) = guard {
        g.done();
    }
    match stored {
        Stored::New => {
            tracing::info!(calibration_id = %id, sensor_id = %sensor_id, kind, "calibration stored");
            if let Some(v) = verdict {
                metrics::counter!("accelcal_verdicts_total", "verdict" => v.as_str()).increment(1);
            }
            Ok(Submitted {
                id,
                result,
                replayed: false,
            })
        }
        Stored::Existing(first) => replay(lab, first).await,
    }
}

/// Submits `upload` as a calibration of `kind` by `principal`: assessed,
/// stored durably, answered; with `key`, at most once per key.
pub async fn submit(
    lab: &Lab,
    principal: &Principal,
    upload: Upload,
    key: Option<IdempotencyKey>,
    kind: Kind,
) -> Result<Submitted, Error> {
    let mut guard = match &key {
        None => None,
        Some(k) => match claim(lab, k).await? {
            Ok(guard) => Some(guard),
            Err(answered) => return Ok(answered),
        },
    };
    let (id, received_at) = (Uuid::now_v7(), Timestamp::now());
    let assessed = kind
        .assess(lab, principal, upload, received_at, id, None)
        .await;
    let assessed = or_release(assessed, &mut guard).await?;
    let Some(rec) = assessed.record else {
        return Err(Error::Internal);
    };
    store(lab, rec, key, guard).await
}
