//! A submission evaluated for an answer: checked, identified and fused on
//! the compute pool, then assessed with what the store knows of its sensor
//! (the sensor type in force, the previous calibration), and its result
//! document rendered once. Shared by `POST /v1/calibrations` (which stores
//! it) and `POST /v1/identify` (which does not).

use bytes::Bytes;
use uuid::Uuid;

use super::AppState;
use super::auth::station;
use super::body::Body;
use super::problem::Problem;
use crate::domain::auth::{Principal, Role};
use crate::domain::field::{Errors, Invalid, Loc};
use crate::domain::metrology::{Previous, assess_calibration};
use crate::domain::nonconformity::{Bearing, HeldBy, bearing, out_of_service};
use crate::domain::review::Supersedes;
use crate::domain::sensor_types::SensorType;
use crate::domain::standards::UsedStandard;
use crate::domain::submission::{Evaluated, ResultView, StandIn, evaluate};
use crate::domain::text::echo;
use crate::domain::timestamp::Timestamp;
use crate::store::{NewCalibration, StandardUse};

/// A submission ready to be answered (and stored).
pub struct Assessed {
    /// The sensor.
    pub sensor_id: String,
    /// The result document, rendered once.
    pub result: Bytes,
    /// What to store, when the caller asked for a stored calibration.
    pub record: Option<NewCalibration>,
}

/// The sensor type in force: the one the submission names (which must
/// exist), else the sensor's — for a sensor whose calibrations are of the
/// submission's kind (`triad`, [`super::triads::wrong_kind`]). Only an admin may re-type a sensor through a
/// submission: a station may name the sensor's current type, or any type
/// while the sensor has none (403 otherwise), since its type decides how its
/// calibrations are judged.
pub async fn sensor_type(
    state: &AppState,
    principal: &Principal,
    sensor_id: &str,
    named: Option<&String>,
    triad: bool,
    now: Timestamp,
) -> Result<Option<SensorType>, Problem> {
    let sensor = state.store.sensor(sensor_id.to_owned(), now).await?;
    if let Some(sensor) = &sensor {
        super::triads::wrong_kind(sensor_id, sensor.latest.triad.is_some(), triad)?;
    }
    let current = sensor.and_then(|sensor| sensor.sensor_type);
    let Some(named) = named else {
        return match current {
            Some(t) => Ok(state.store.sensor_type(t).await?),
            None => Ok(None),
        };
    };
    if let Some(current) = &current
        && current != named
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
        return Err(Problem::forbidden(why.clone())
            .with_errors(Invalid::one(Loc::Root.key("sensor_type"), why)));
    }
    match state.store.sensor_type(named.clone()).await? {
        Some(t) => Ok(Some(t)),
        None => Err(Problem::validation(Invalid::one(
            Loc::Root.key("sensor_type"),
            format!(
                "no sensor type `{}`; create it first with PUT /v1/sensor-types/{}",
                echo(named),
                echo(named)
            ),
        ))),
    }
}

/// Resolves the standards `e` names against the registry, for a test
/// performed at `performed_at` ([`resolve`]); the stand's indexing error
/// and the gravity value's relative uncertainty become the submission's
/// stand.
async fn resolve_standards(
    state: &AppState,
    e: &mut Evaluated,
    performed_at: Timestamp,
) -> Result<(), Problem> {
    let Some(named) = e.submission.standards.clone() else {
        return Ok(());
    };
    let roles = [
        ("stand", Some(named.stand.clone())),
        ("thermometer", named.thermometer.clone()),
        ("gravity", named.gravity.clone()),
    ];
    let r = resolve(state, &roles, performed_at).await?;
    e.submission.stand = Some(r.stand);
    e.submission.standards_used = r.used;
    e.submission.held_by = r.held_by;
    Ok(())
}

/// The standards a submission names, resolved ([`resolve`]).
pub struct Resolved {
    /// The stand they make.
    pub stand: StandIn,
    /// Each as used: the certificate in force and its parameters.
    pub used: Vec<UsedStandard>,
    /// The nonconformities that hold the test.
    pub held_by: Vec<HeldBy>,
}

impl Resolved {
    /// What the store judges of them as it stores the test.
    pub fn uses(used: &[UsedStandard]) -> Vec<StandardUse> {
        used.iter()
            .map(|u| StandardUse {
                standard_id: u.standard_id.clone(),
                calibrated_at: u.certificate.calibrated_at,
            })
            .collect()
    }
}

/// Resolves the standards named by role against the registry, for a test performed
/// at `performed_at`: each must exist, be of its role's kind, be in
/// calibration then (by its certificate or an earlier one) and in service —
/// no recorded nonconformity of it found before `performed_at` without a
/// certificate since ([`bearing`]); every problem is a 422 naming the role
/// (`/standards/stand`, …). Answers the stand they make — the stand's
/// indexing error and the gravity value's relative uncertainty as the
/// certificate in force at `performed_at` states them, each with its
/// degrees of freedom — the standards as used, and the nonconformities in
/// whose windows the test was performed (it will be stored held).
/// Single-axis and triad submissions alike.
pub async fn resolve(
    state: &AppState,
    roles: &[(&str, Option<String>)],
    performed_at: Timestamp,
) -> Result<Resolved, Problem> {
    let mut errors = Errors::default();
    let mut used = Vec::new();
    let root = Loc::Root;
    let standards_at = root.key("standards");
    for (role, id) in roles {
        let (role, Some(id)) = (*role, id) else {
            continue;
        };
        let at = standards_at.key(role);
        match state.store.standard(id.clone()).await? {
            None => errors.add(
                at,
                format!(
                    "no standard `{}`; an admin records it first (PUT /v1/standards/{})",
                    echo(id),
                    echo(id)
                ),
            ),
            Some(s) => match s.used_as(role, performed_at) {
                Ok(u) => used.push(u),
                Err(why) => errors.add(at, why),
            },
        }
    }
    let mut held_by = Vec::new();
    if !used.is_empty() {
        let ids = used.iter().map(|u| u.standard_id.clone()).collect();
        let findings = state.store.findings(ids).await?;
        for u in &used {
            for nc in findings.iter().filter(|nc| nc.standard_id == u.standard_id) {
                match bearing(nc, u.certificate.calibrated_at, performed_at) {
                    Bearing::Clear => {}
                    Bearing::Held => held_by.push(HeldBy::from(nc)),
                    Bearing::OutOfService => {
                        errors.add(standards_at.key(&u.role), out_of_service(nc, performed_at))
                    }
                }
            }
        }
    }
    if !errors.is_empty() {
        return Err(Problem::validation(errors.into_invalid()));
    }
    // Each parameter with the degrees of freedom its certificate gives it.
    let angle = used.iter().find_map(|u| {
        u.parameters
            .angle_std_arcsec
            .map(|a| (a, u.parameters.degrees_of_freedom))
    });
    let gravity = used.iter().find_map(|u| {
        u.parameters
            .gravity_rel_std
            .map(|g| (g, u.parameters.degrees_of_freedom))
    });
    let stand = StandIn {
        id: used.first().map(|u| u.standard_id.clone()),
        angle_std_arcsec: angle.map_or(0.0, |a| a.0),
        gravity_rel_std: gravity.map_or(0.0, |g| g.0),
        angle_dof: angle.and_then(|a| a.1),
        gravity_dof: gravity.and_then(|g| g.1),
    };
    Ok(Resolved {
        stand,
        used,
        held_by,
    })
}

/// Evaluates a body for `principal`; with `id`, also builds the record to
/// store under that id — which, with `supersedes`, records the calibration
/// it corrects.
pub async fn assess(
    state: &AppState,
    principal: &Principal,
    body: Body,
    received_at: Timestamp,
    id: Option<Uuid>,
    supersedes: Option<Supersedes>,
) -> Result<Assessed, Problem> {
    let (bytes, content_type) = (body.bytes.clone(), body.content_type.clone());
    let size = bytes.len();
    let who = principal.clone();
    let (mut evaluated, station_id) = state
        .compute_for(
            size,
            move || -> Result<(Evaluated, Option<String>), Problem> {
                let e = evaluate(body.media, &body.bytes, received_at)?;
                let station_id = station(&who, e.submission.station_id.as_deref())?;
                Ok((e, station_id))
            },
        )
        .await??;
    let sensor_type = sensor_type(
        state,
        principal,
        &evaluated.submission.sensor_id,
        evaluated.submission.sensor_type.as_ref(),
        false,
        received_at,
    )
    .await?;
    let performed_at = evaluated.submission.performed_at.unwrap_or(received_at);
    resolve_standards(state, &mut evaluated, performed_at).await?;
    let previous = state
        .store
        .previous_calibration(
            evaluated.submission.sensor_id.clone(),
            performed_at,
            state.web.basis,
        )
        .await?
        .map(|c| Previous {
            id: c.id,
            unit: c.unit,
            coefficients: c.coefficients,
        });
    let submitted_by = principal.id.clone();
    state
        .compute_for(size, move || -> Result<Assessed, Problem> {
            let e = &evaluated;
            let type_id = sensor_type.as_ref().map(|t| t.type_id.as_str());
            let metrology =
                assess_calibration(e, performed_at, sensor_type.as_ref(), previous.as_ref())?;
            let mut view = ResultView::new(
                e,
                id,
                station_id.as_deref(),
                received_at,
                type_id,
                &metrology,
            );
            view.supersedes = supersedes;
            let result = Bytes::from(serde_json::to_vec(&view).map_err(|err| {
                tracing::error!(error = %err, "a result did not serialise");
                Problem::internal()
            })?);
            let fused = &e.calibration.fused;
            let record = id.map(|id| NewCalibration {
                id,
                sensor_id: e.submission.sensor_id.clone(),
                performed_at,
                received_at,
                unit: e.submission.unit.clone(),
                model: e.submission.test.model().clone(),
                runs: e.calibration.runs.len(),
                coefficients: fused.coefficients.clone(),
                std_errors: fused.std_errors.clone(),
                result: result.clone(),
                submission: bytes,
                content_type,
                submitted_by,
                station_id: station_id.clone(),
                sensor_type: type_id.map(str::to_owned),
                assigns_type: e.submission.sensor_type.is_some(),
                verdict: metrology.decision.as_ref().map(|d| d.verdict),
                due_at: metrology.due_at,
                expanded: Some(metrology.uncertainty.expanded()),
                triad: None,
                standards: Resolved::uses(&e.submission.standards_used),
            });
            Ok(Assessed {
                sensor_id: e.submission.sensor_id.clone(),
                result,
                record,
            })
        })
        .await?
}
