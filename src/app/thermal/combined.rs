//! A temperature model's body naming stored calibrations, read (issue 45
//! item 1): each named calibration looked up — of the sensor named, of the
//! kind the model is fitted to (single axes, or triads at one
//! temperature), in a state that counts and not held under review by a
//! standard's nonconformity (the model would not be) — and its stored
//! submission read
//! again on the compute pool, performed when it was; together they make
//! one submission ([`combine`], [`combine_triads`]), to which the model is
//! fitted as to one sent whole. Each refusal names the calibration
//! (`/calibrations/<i>`).

use bytes::Bytes;
use uuid::Uuid;

use super::super::subject::station;
use super::super::{Error, Lab, Upload};
use crate::domain::auth::Principal;
use crate::domain::field::Loc;
use crate::domain::standards::UsedStandard;
use crate::domain::submission::{Submission, evaluate};
use crate::domain::text::echo;
use crate::domain::thermal::combine::{
    Constituent, FromCalibrations, TriadConstituent, combine, combine_triads, unusable,
};
use crate::domain::timestamp::Timestamp;
use crate::domain::triad::TriadSubmission;
use crate::domain::typed;

/// The kind of calibration a model is fitted to.
#[derive(Clone, Copy)]
enum Of {
    SingleAxis,
    Triad,
}

/// What a named calibration holds for a model: its id, when it was
/// performed, its stored submission and its stored result.
struct Stored {
    id: Uuid,
    performed_at: Timestamp,
    content_type: String,
    submission: Bytes,
    result: Option<Bytes>,
}

/// The calibrations named in the JSON body `json` for `principal`, of
/// kind `of`: the body, the station it names (checked against the
/// token's), the ids in the order named and what each holds.
async fn lookup(
    lab: &Lab,
    principal: &Principal,
    json: &[u8],
    of: Of,
) -> Result<(FromCalibrations, Option<String>, Vec<Uuid>, Vec<Stored>), Error> {
    let body: FromCalibrations = typed::from_json(json)?;
    let ids = body.check()?;
    let station_id = station(principal, body.station_id.as_deref())?;
    let root = Loc::Root;
    let named = root.key("calibrations");
    let mut stored = Vec::with_capacity(ids.len());
    for (i, &id) in ids.iter().enumerate() {
        let refuse = |why: String| Error::invalid(named.index(i), why);
        let Some(c) = lab.store.calibration_summary(id).await? else {
            return Err(refuse(format!("no calibration with id {id}")));
        };
        if c.sensor_id != body.sensor_id {
            return Err(refuse(format!(
                "calibration {id} is of sensor `{}`, not `{}`",
                echo(&c.sensor_id),
                echo(&body.sensor_id)
            )));
        }
        let other = match of {
            Of::SingleAxis if c.triad.is_some() => Some("a triad's"),
            Of::Triad if c.triad.is_none() => Some("a single axis's"),
            _ if c.thermal.is_some() || c.thermal_triad.is_some() => Some("a temperature model"),
            _ => None,
        };
        if let Some(what) = other {
            let kind = match of {
                Of::SingleAxis => "a single axis's model is fitted to single-axis calibrations",
                Of::Triad => "a triad's model is fitted to triad calibrations at one temperature",
            };
            return Err(refuse(format!("calibration {id} is {what}: {kind}")));
        }
        if let Some(why) = unusable(id, c.state) {
            return Err(refuse(why));
        }
        let Some(s) = lab.store.submission(id).await? else {
            tracing::error!(calibration_id = %id, "a stored calibration has no submission");
            return Err(Error::Internal);
        };
        stored.push(Stored {
            id,
            performed_at: c.performed_at,
            content_type: s.content_type,
            submission: s.body,
            result: lab.store.calibration_result(id).await?,
        });
    }
    Ok((body, station_id, ids, stored))
}

/// The submission the single-axis calibrations named in the JSON body
/// `json` make for `principal`, the station it names (checked against the
/// token's) and the ids, in the order named.
pub async fn read(
    lab: &Lab,
    principal: &Principal,
    json: &[u8],
) -> Result<(Submission, Option<String>, Vec<Uuid>), Error> {
    let (body, station_id, ids, stored) = lookup(lab, principal, json, Of::SingleAxis).await?;
    let size = stored.iter().map(|s| s.submission.len()).sum();
    let (sensor_id, station) = (body.sensor_id, station_id.clone());
    let sub = lab
        .compute_for(size, move || -> Result<Submission, Error> {
            let mut parts = Vec::with_capacity(stored.len());
            for (i, s) in stored.into_iter().enumerate() {
                parts.push(constituent(i, s)?);
            }
            Ok(combine(&sensor_id, station, parts)?)
        })
        .await??;
    Ok((sub, station_id, ids))
}

/// The triad submission the triad calibrations named in the JSON body
/// `json` make for `principal`, with the standards they used, the station
/// it names and the ids, in the order named.
pub async fn read_triads(
    lab: &Lab,
    principal: &Principal,
    json: &[u8],
) -> Result<
    (
        TriadSubmission,
        Vec<UsedStandard>,
        Option<String>,
        Vec<Uuid>,
    ),
    Error,
> {
    let (body, station_id, ids, stored) = lookup(lab, principal, json, Of::Triad).await?;
    let size = stored.iter().map(|s| s.submission.len()).sum();
    let (sensor_id, station) = (body.sensor_id, station_id.clone());
    let (sub, standards) = lab
        .compute_for(size, move || {
            let mut parts = Vec::with_capacity(stored.len());
            for (i, s) in stored.into_iter().enumerate() {
                let (id, performed_at) = (s.id, s.performed_at);
                let standards = used(s.result.as_ref());
                let upload = Upload::stored(s.content_type, s.submission);
                let submission = super::super::triad::read(&upload).map_err(|e| {
                    Error::invalid(
                        Loc::Root.key("calibrations").index(i),
                        format!("calibration {id}'s submission does not read again: {e}"),
                    )
                })?;
                parts.push(TriadConstituent {
                    id,
                    performed_at,
                    submission,
                    standards,
                });
            }
            Ok::<_, Error>(combine_triads(&sensor_id, station, parts)?)
        })
        .await??;
    Ok((sub, standards, station_id, ids))
}

/// The standards a stored result document records as used.
fn used(result: Option<&Bytes>) -> Vec<UsedStandard> {
    #[derive(serde::Deserialize)]
    struct Used {
        #[serde(default)]
        standards: Vec<UsedStandard>,
    }
    result
        .and_then(|r| serde_json::from_slice::<Used>(r).ok())
        .map(|u| u.standards)
        .unwrap_or_default()
}

/// The `i`th calibration named, read again.
fn constituent(i: usize, s: Stored) -> Result<Constituent, Error> {
    let upload = Upload::stored(s.content_type, s.submission);
    let id = s.id;
    let mut submission = evaluate(upload.media, &upload.bytes, s.performed_at)
        .map_err(|e| {
            Error::invalid(
                Loc::Root.key("calibrations").index(i),
                format!("calibration {id}'s submission does not read again: {e}"),
            )
        })?
        .submission;
    submission.performed_at = Some(s.performed_at);
    let standards = used(s.result.as_ref());
    Ok(Constituent {
        id,
        submission,
        standards,
    })
}
