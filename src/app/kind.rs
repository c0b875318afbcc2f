//! The kinds of calibration a station submits, and the one place an act
//! asks a kind to assess a submission: a new kind is a variant here and
//! its own assessment module ([`super::single_axis`], [`super::triad`]).

use uuid::Uuid;

use super::{Assessed, Error, Lab, Upload, single_axis, triad};
use crate::domain::auth::Principal;
use crate::domain::review::Supersedes;
use crate::domain::timestamp::Timestamp;
use crate::store::CalibrationSummary;

/// A kind of calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// One pendulous accelerometer's static model, from tumble tests.
    SingleAxis,
    /// A triad's u = b + S g.
    Triad,
}

impl Kind {
    /// The kind of a stored calibration.
    pub fn of(c: &CalibrationSummary) -> Kind {
        if c.triad.is_some() {
            Kind::Triad
        } else {
            Kind::SingleAxis
        }
    }

    /// `upload` assessed as this kind for `principal`, received at
    /// `received_at`, to be stored under `id` — recording, with
    /// `supersedes`, the calibration it corrects.
    pub async fn assess(
        self,
        lab: &Lab,
        principal: &Principal,
        upload: Upload,
        received_at: Timestamp,
        id: Uuid,
        supersedes: Option<Supersedes>,
    ) -> Result<Assessed, Error> {
        match self {
            Kind::SingleAxis => {
                single_axis::assess(lab, principal, upload, received_at, Some(id), supersedes).await
            }
            Kind::Triad => triad::assess(lab, principal, upload, received_at, id, supersedes).await,
        }
    }
}
