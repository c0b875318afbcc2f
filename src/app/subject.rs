//! Who and what a submission is about, asked of the records before any
//! kind of calibration computes: the station it is recorded on, the sensor
//! type it is judged by, and the kind of calibration its sensor holds.

use super::{Error, Lab};
use crate::domain::auth::{Principal, Role};
use crate::domain::field::{Invalid, Loc};
use crate::domain::sensor_types::SensorType;
use crate::domain::text::echo;
use crate::domain::timestamp::Timestamp;
use crate::store::{CalibrationSummary, SensorSummary};

/// The refusal of a `triad` (or single-axis) submission for a sensor whose
/// calibrations are of the other kind (`is_triad`).
pub fn wrong_kind(sensor_id: &str, is_triad: bool, triad: bool) -> Result<(), Error> {
    if is_triad == triad {
        return Ok(());
    }
    let id = echo(sensor_id);
    Err(Error::WrongKind(if triad {
        format!(
            "sensor `{id}` holds single-axis calibrations; a triad is calibrated under an id of \
             its own (a sensor's calibrations are all of one kind)"
        )
    } else {
        format!(
            "sensor `{id}` is a triad: its calibrations are submitted with \
             POST /v1/calibrations/triad"
        )
    }))
}

/// What the records hold of a submission's sensor, read once: its summary
/// (`None` for a sensor with no calibration that counts) and the sensor
/// type in force ([`in_force`]).
pub struct Subject {
    /// The sensor's summary, as read before the submission was assessed.
    pub sensor: Option<SensorSummary>,
    /// The sensor type the submission is judged by.
    pub sensor_type: Option<SensorType>,
}

impl Subject {
    /// The sensor's latest calibration that counts on the lab's basis and
    /// was performed strictly before `performed_at`: what as-found is
    /// judged against. From the summary already read when it can tell
    /// ([`SensorSummary::previous_before`]); none for a sensor with no
    /// summary (no calibration of it counts, on either basis); else asked
    /// of the records.
    pub async fn previous(
        &self,
        lab: &Lab,
        performed_at: Timestamp,
    ) -> Result<Option<CalibrationSummary>, Error> {
        let Some(sensor) = &self.sensor else {
            return Ok(None);
        };
        if let Some(latest) = sensor.previous_before(performed_at, lab.basis) {
            return Ok(Some(latest.clone()));
        }
        Ok(lab
            .store
            .previous_calibration(sensor.sensor_id.clone(), performed_at, lab.basis)
            .await?)
    }
}

/// The sensor's summary and the sensor type in force: the one the
/// submission names (which must exist), else the sensor's — for a sensor
/// whose calibrations are of the submission's kind (`triad`,
/// [`wrong_kind`]). Only an admin may re-type a sensor through a
/// submission: a station may name the sensor's current type, or any type
/// while the sensor has none (forbidden otherwise), since its type decides
/// how its calibrations are judged.
pub async fn in_force(
    lab: &Lab,
    principal: &Principal,
    sensor_id: &str,
    named: Option<&String>,
    triad: bool,
    now: Timestamp,
) -> Result<Subject, Error> {
    let sensor = lab.store.sensor(sensor_id.to_owned(), now).await?;
    if let Some(sensor) = &sensor {
        wrong_kind(sensor_id, sensor.latest.triad.is_some(), triad)?;
    }
    let current = sensor.as_ref().and_then(|s| s.sensor_type.as_ref());
    let Some(named) = named else {
        let sensor_type = match current {
            Some(t) => lab.store.sensor_type(t.clone()).await?,
            None => None,
        };
        return Ok(Subject {
            sensor,
            sensor_type,
        });
    };
    if let Some(current) = &current
        && *current != named
        && principal.role < Role::Admin
    {
        let why = format!(
            "sensor `{}` is of type `{}`; a {} token may name that type or none, not `{}` \
             (an admin changes a sensor's type with PUT /v1/sensors/{})",
            echo(sensor_id),
            echo(current),
            principal.role,
            echo(named),
            echo(sensor_id),
        );
        return Err(Error::Forbidden {
            fields: Some(Invalid::one(Loc::Root.key("sensor_type"), why.clone())),
            why,
        });
    }
    match lab.store.sensor_type(named.clone()).await? {
        Some(t) => Ok(Subject {
            sensor,
            sensor_type: Some(t),
        }),
        None => Err(Error::invalid(
            Loc::Root.key("sensor_type"),
            format!(
                "no sensor type `{}`; create it first with PUT /v1/sensor-types/{}",
                echo(named),
                echo(named)
            ),
        )),
    }
}

/// The station recorded on (or named in) a submission: a bound token's
/// station, which the submission may repeat but not contradict; otherwise
/// the submission's `station_id` (an unbound station token may name any
/// station).
pub fn station(principal: &Principal, claimed: Option<&str>) -> Result<Option<String>, Error> {
    match (&principal.station_id, claimed) {
        (Some(bound), Some(claimed)) if bound != claimed => Err(Error::Forbidden {
            why: format!(
                "this token is bound to station `{bound}` and cannot act as `{}`",
                echo(claimed)
            ),
            fields: None,
        }),
        (Some(bound), _) => Ok(Some(bound.clone())),
        (None, claimed) => Ok(claimed.map(str::to_owned)),
    }
}
