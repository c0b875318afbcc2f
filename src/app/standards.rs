//! The reference standards a submission names, resolved against the
//! registry for the moment the test was performed — single-axis and triad
//! submissions alike.

use super::{Error, Lab};
use crate::domain::field::{Errors, Loc};
use crate::domain::nonconformity::{Bearing, HeldBy, bearing, out_of_service};
use crate::domain::standards::UsedStandard;
use crate::domain::submission::StandIn;
use crate::domain::text::echo;
use crate::domain::timestamp::Timestamp;
use crate::store::StandardUse;

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

/// Resolves the standards named by role against the registry, for a test
/// performed at `performed_at`: each must exist, be of its role's kind, be
/// in calibration then (by its certificate or an earlier one) and in
/// service — no recorded nonconformity of it found before `performed_at`
/// without a certificate since ([`bearing`]); every problem is a field
/// error naming the role (`/standards/stand`, …). Answers the stand they
/// make — the stand's indexing error and the gravity value's relative
/// uncertainty as the certificate in force at `performed_at` states them,
/// each with its degrees of freedom — the standards as used, and the
/// nonconformities in whose windows the test was performed (it will be
/// stored held).
pub async fn resolve(
    lab: &Lab,
    roles: &[(&str, Option<String>)],
    performed_at: Timestamp,
) -> Result<Resolved, Error> {
    let mut errors = Errors::default();
    let mut used = Vec::new();
    let root = Loc::Root;
    let standards_at = root.key("standards");
    for (role, id) in roles {
        let (role, Some(id)) = (*role, id) else {
            continue;
        };
        let at = standards_at.key(role);
        match lab.store.standard(id.clone()).await? {
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
        let findings = lab.store.findings(ids).await?;
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
        return Err(Error::Invalid(errors.into_invalid()));
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
