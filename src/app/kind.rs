//! The kinds of calibration a station submits, and the one place an act
//! asks a kind to assess a submission: a new kind is a variant here and
//! its own assessment module ([`super::single_axis`], [`super::triad`],
//! [`super::thermal`]).

use std::pin::Pin;

use uuid::Uuid;

use super::{Assessed, Error, Lab, Upload, single_axis, thermal, triad};
use crate::domain::auth::Principal;
use crate::domain::review::Supersedes;
use crate::domain::thermal::Fit;
use crate::domain::timestamp::Timestamp;
use crate::store::CalibrationSummary;

/// A kind's assessment of one submission, boxed ([`Kind::assess`]).
type Assessing<'a> = Pin<Box<dyn Future<Output = Result<Assessed, Error>> + Send + 'a>>;

/// A kind of calibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// One pendulous accelerometer's static model, from tumble tests.
    SingleAxis,
    /// A triad's u = b + S g.
    Triad,
    /// A single axis's static model over temperature, fitted so.
    Thermal(Fit),
    /// A triad's `b` and `S` over temperature, fitted so.
    ThermalTriad(Fit),
}

impl Kind {
    /// The kind of a stored calibration.
    /// A temperature model is fitted again as it was: with the parameters
    /// it was fitted with (which were checked when it was).
    pub fn of(c: &CalibrationSummary) -> Kind {
        if let Some(t) = &c.thermal_triad {
            return Kind::ThermalTriad(t.fitted_with.checked().unwrap_or_default());
        }
        if c.triad.is_some() {
            return Kind::Triad;
        }
        match c.thermal.as_ref().map(|t| t.fitted_with.checked()) {
            Some(Ok(fit)) => Kind::Thermal(fit),
            // Parameters stored that no longer check cannot be: a default
            // fit then, which the stored model's own checks still guard.
            Some(Err(_)) => Kind::Thermal(Fit::default()),
            None => Kind::SingleAxis,
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
        // Each kind's future is boxed: held inline, every submission's
        // would be as large as the largest kind's (a triad's, 15 KB) and
        // copied whole into each future that awaits it (BENCHMARKS.md
        // "Futures and records copied").
        let assessed: Assessing<'_> = match self {
            Kind::SingleAxis => Box::pin(single_axis::assess(
                lab,
                principal,
                upload,
                received_at,
                Some(id),
                supersedes,
            )),
            Kind::Triad => Box::pin(triad::assess(
                lab,
                principal,
                upload,
                received_at,
                id,
                supersedes,
            )),
            Kind::Thermal(fit) => Box::pin(thermal::assess(
                lab,
                principal,
                upload,
                received_at,
                id,
                supersedes,
                fit,
            )),
            Kind::ThermalTriad(fit) => Box::pin(thermal::triad::assess(
                lab,
                principal,
                upload,
                received_at,
                id,
                supersedes,
                fit,
            )),
        };
        assessed.await
    }
}
