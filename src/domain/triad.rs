//! Triad submissions (issue 30): three outputs at once, `u = b + S g`.
//!
//! One body, three forms, exactly one of which is given:
//!
//! * **known orientations** — `orientations` (gravity vectors in the body
//!   frame, in g, or a named set: `six_faces`, `cube24`) and `runs`, each
//!   run's samples of `(u_x, u_y, u_z)` per position: each axis is
//!   identified and fused by the single-axis method over the shared
//!   positions ([`accelcal_core::triad`]);
//! * **unknown orientations** — `static_positions`, each position's samples:
//!   `b` and `T = S⁻¹` from the gravity magnitude
//!   ([`accelcal_core::gravity_fit`]);
//! * **a recording** — `recording` (`rate_hz`, samples, optional `detector`
//!   parameters): its static intervals ([`accelcal_core::static_intervals`])
//!   become the static positions.
//!
//! [`TriadBody::check`] names every fault by JSON pointer; [`compute`]
//! answers a [`TriadResult`], whose `b`, `S` and `T` also feed the exports
//! ([`super::triad_export`]).

use accelcal_core::gravity_budget::{self, GravityBudget};
use accelcal_core::gravity_fit::{self, GravityFit, GravityFitError, MIN_POSITIONS};
use accelcal_core::static_intervals::{self, DetectError, Detection, Detector, Rejection};
use accelcal_core::thermal::TOLERANCE_K;
use accelcal_core::triad::{AXES, Triad, TriadError, TriadRun, TriadTest, six_faces};
use std::collections::BTreeMap;

use accelcal_core::adequacy::model_uncertainty;
use accelcal_core::coverage::Coverage;
use accelcal_core::decision::{Limit, Rule, TermDecision, Verdict, decide};
use accelcal_core::quality;
use accelcal_core::uncertainty::{ARCSEC, Stand, TermBudget, budget};
use accelcal_core::{Term, TermMap};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::field::{Errors, Invalid, Loc};
use super::limits::{
    MAX_ANGLE_STD_ARCSEC, MAX_BATCHES, MAX_GRAVITY_REL_STD, MAX_ID_CHARS, MAX_POSITIONS,
    MAX_READING, MAX_RUNS, MAX_TOTAL_SAMPLES, MAX_UNIT_CHARS,
};
use super::standards::UsedStandard;
use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

mod body;
mod check;
mod compute;
mod result;

pub use body::*;
pub use compute::*;
pub use result::*;
