//! Reverse trace (issue 29 item 3): a reference standard found
//! nonconforming, and the calibrations it may have spoiled.
//!
//! When a standard is found out of tolerance at `found_at`, every
//! calibration made with it since it was last known good is suspect: from
//! `last_known_good_at` when the laboratory knows it (an intermediate check
//! that passed), otherwise from the calibration of the standard whose
//! certificate was in force at `found_at`, up to `found_at`:
//!
//! ```text
//! window = [last_known_good_at, or that certificate's calibrated_at;  found_at]
//! ```
//!
//! Each calibration in the window that counts (`submitted`, `approved`) is
//! put `under_review` by a `hold` signature ([`super::review`]): its
//! coefficients stop being usable until a reviewer records a disposition —
//! approves it again with the reason (`no effect: …`), or withdraws or
//! supersedes it. Calibrations already withdrawn, rejected, superseded or
//! under review are listed, and left as they are.
//!
//! The nonconformity bears on every test with the standard, whenever it is
//! submitted ([`bearing`]): one performed in the window is stored held; one
//! performed after `found_at` under a certificate calibrated before it (the
//! standard not yet repaired and recalibrated) is refused — the standard is
//! out of service until a new certificate is recorded. A correction or a
//! reprocessing of a held calibration that still uses the standard is held
//! under the same nonconformity.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::audit::Actor;
use super::auth::Role;
use super::field::Invalid;
use super::review::{Action, Signature, State, check_reason};
use super::standards::Standard;
use super::timestamp::Timestamp;

/// The body of `POST /v1/standards/{standard_id}/nonconformity`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct NonconformityBody {
    /// When the standard was found nonconforming (RFC 3339; not in the
    /// future).
    #[schema(value_type = String, format = DateTime)]
    pub found_at: String,
    /// When it was last known to be good, if known (an intermediate check);
    /// otherwise the window starts at its calibration in force at
    /// `found_at`.
    #[serde(default)]
    #[schema(value_type = Option<String>, format = DateTime)]
    pub last_known_good_at: Option<String>,
    /// What was found (1–2 000 characters).
    #[schema(value_type = String, min_length = 1, max_length = 2000)]
    pub reason: String,
}

/// A recorded nonconformity of a standard.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Nonconformity {
    /// Its id.
    pub id: uuid::Uuid,
    /// The standard.
    pub standard_id: String,
    /// When it was found nonconforming.
    pub found_at: Timestamp,
    /// When it was last known good, as given.
    pub last_known_good_at: Option<Timestamp>,
    /// Where the affected window starts: `last_known_good_at`, or the
    /// calibration of the standard in force at `found_at`.
    pub window_from: Timestamp,
    /// What was found.
    pub reason: String,
    /// When accelcal recorded it.
    pub recorded_at: Timestamp,
    /// Who recorded it.
    pub recorded_by: Actor,
}

fn instant(pointer: &str, raw: &str) -> Result<Timestamp, Invalid> {
    Timestamp::parse(raw).map_err(|e| Invalid::one(pointer, e.to_string()))
}

impl NonconformityBody {
    /// The nonconformity of `standard` this body describes, recorded at
    /// `now` by `by` as `id`; or which field is wrong and why.
    pub fn check(
        self,
        id: uuid::Uuid,
        standard: &Standard,
        now: Timestamp,
        by: Actor,
    ) -> Result<Nonconformity, Invalid> {
        let found_at = instant("/found_at", &self.found_at)?;
        if found_at > now {
            return Err(Invalid::one("/found_at", "is in the future"));
        }
        let last_known_good_at = self
            .last_known_good_at
            .as_deref()
            .map(|raw| instant("/last_known_good_at", raw))
            .transpose()?;
        let window_from = match last_known_good_at {
            Some(good) if good > found_at => {
                return Err(Invalid::one(
                    "/last_known_good_at",
                    "is after found_at: the standard cannot have been known good after it was \
                     found nonconforming",
                ));
            }
            Some(good) => good,
            None => in_force_since(standard, found_at).ok_or_else(|| {
                Invalid::one(
                    "/found_at",
                    format!(
                        "is before every calibration of standard `{}` on record; give \
                         last_known_good_at",
                        standard.standard_id
                    ),
                )
            })?,
        };
        let reason =
            check_reason(Some(&self.reason)).map_err(|why| Invalid::one("/reason", why))?;
        Ok(Nonconformity {
            id,
            standard_id: standard.standard_id.clone(),
            found_at,
            last_known_good_at,
            window_from,
            reason,
            recorded_at: now,
            recorded_by: by,
        })
    }
}

/// A nonconformity that holds a calibration as it is stored, as its result
/// names it.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct HeldBy {
    /// The nonconformity.
    pub nonconformity_id: uuid::Uuid,
    /// Its standard.
    pub standard_id: String,
    /// When the standard was found nonconforming.
    pub found_at: Timestamp,
    /// What was found.
    pub reason: String,
}

impl From<&Nonconformity> for HeldBy {
    fn from(nc: &Nonconformity) -> Self {
        HeldBy {
            nonconformity_id: nc.id,
            standard_id: nc.standard_id.clone(),
            found_at: nc.found_at,
            reason: nc.reason.clone(),
        }
    }
}

/// How a nonconformity bears on a test performed with its standard at `at`
/// under the certificate calibrated at `certificate_calibrated_at` (the one
/// in force at `at`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bearing {
    /// Not at all: performed before the window, or after a recalibration
    /// that followed `found_at`.
    Clear,
    /// Performed in the window `[window_from, found_at]`: stored held.
    Held,
    /// Performed after `found_at` under a certificate from before it: the
    /// standard was out of service; refused.
    OutOfService,
}

/// How `nc` bears on a test performed at `at` under the certificate
/// calibrated at `certificate_calibrated_at` ([`Bearing`]).
pub fn bearing(nc: &Nonconformity, certificate_calibrated_at: Timestamp, at: Timestamp) -> Bearing {
    if at < nc.window_from {
        Bearing::Clear
    } else if at <= nc.found_at {
        Bearing::Held
    } else if certificate_calibrated_at <= nc.found_at {
        Bearing::OutOfService
    } else {
        Bearing::Clear
    }
}

/// Why a standard out of service refuses a test ([`Bearing::OutOfService`]).
pub fn out_of_service(nc: &Nonconformity, at: Timestamp) -> String {
    format!(
        "standard `{}` was found nonconforming on {} (nonconformity {}: {}) and is out of \
         service until a new certificate is recorded; a test performed at {at} used it \
         unrepaired — recalibrate it, record the new certificate (PUT /v1/standards/{}), \
         then repeat the test",
        nc.standard_id, nc.found_at, nc.id, nc.reason, nc.standard_id
    )
}

/// The comment of a hold placed on a calibration performed inside the
/// windows of `held_by`.
pub fn hold_reason(held_by: &[&Nonconformity]) -> String {
    let each: Vec<String> = held_by
        .iter()
        .map(|nc| {
            format!(
                "standard {} found nonconforming {} (nonconformity {}): {}",
                nc.standard_id, nc.found_at, nc.id, nc.reason
            )
        })
        .collect();
    format!(
        "performed with a standard inside a nonconformity's window: {}",
        each.join("; ")
    )
}

/// The `hold` signature, `seq`-th, of a calibration stored at `at` inside
/// the windows of `held_by` (at least one): signed in the name of the one
/// who recorded the first of them, since the hold follows from that record.
pub fn hold_on_storing(held_by: &[&Nonconformity], seq: u32, at: Timestamp) -> Signature {
    let by = &held_by[0].recorded_by;
    Signature {
        seq,
        action: Action::Hold,
        state: State::UnderReview,
        meaning: Action::Hold.meaning().to_owned(),
        token_id: by.token_id.clone(),
        role: Role::parse(&by.role).unwrap_or(Role::Admin),
        holder: by.holder.clone(),
        signed_at: at,
        comment: Some(hold_reason(held_by)),
        superseded_by: None,
    }
}

/// When the calibration of `standard` in force at `at` was made: the
/// latest of its certificates (the current one and the earlier ones)
/// calibrated at or before `at`.
pub fn in_force_since(standard: &Standard, at: Timestamp) -> Option<Timestamp> {
    std::iter::once(standard.certificate.calibrated_at)
        .chain(standard.earlier.iter().map(|p| p.certificate.calibrated_at))
        .filter(|t| *t <= at)
        .max()
}

/// A calibration a nonconformity concerns, and where it stands now.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Affected {
    /// The calibration.
    pub calibration_id: uuid::Uuid,
    /// Its sensor.
    pub sensor_id: String,
    /// When it was performed (within the window).
    pub performed_at: Timestamp,
    /// Its state when the nonconformity was recorded.
    pub state_found: State,
    /// Its state now.
    pub state: State,
    /// The calibration that stands for it now when it was superseded (the
    /// last of its replacements), with that one's state.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub replaced_by: Option<Replacement>,
    /// What became of it: `under_review` (held, in itself or in the
    /// replacement that stands for it: no disposition yet), `re_approved`
    /// (a reviewer recorded a disposition and approved it again),
    /// `withdrawn`, `rejected`, `superseded` (replaced by a calibration that
    /// is not held), or `unchanged` (it no longer counted when the
    /// nonconformity was recorded, and was left as it was).
    pub outcome: Outcome,
}

/// The calibration that stands for a superseded one.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Replacement {
    /// Its id.
    pub calibration_id: uuid::Uuid,
    /// Its state now.
    pub state: State,
}

/// What became of an affected calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = TraceOutcome)]
pub enum Outcome {
    /// Under review, not yet resolved.
    UnderReview,
    /// Approved again by a reviewer.
    ReApproved,
    /// Withdrawn since.
    Withdrawn,
    /// Superseded by a calibration that is not held.
    Superseded,
    /// Rejected since (in itself or in its replacement).
    Rejected,
    /// Left as it was (it did not count, or was under review already).
    Unchanged,
}

impl Outcome {
    /// The outcome of a calibration found in `found`, now in `now`, and,
    /// when superseded, standing for it now `replacement` (the last of its
    /// replacements) in its state: a superseded calibration is dealt with
    /// only when what replaced it is not held.
    pub fn of(found: State, now: State, replacement: Option<State>) -> Outcome {
        if !matches!(found, State::Submitted | State::Approved) {
            return Outcome::Unchanged;
        }
        match (now, replacement) {
            (State::UnderReview, _) | (State::Superseded, Some(State::UnderReview)) => {
                Outcome::UnderReview
            }
            (State::Approved, _) => Outcome::ReApproved,
            (State::Withdrawn, _) | (State::Superseded, Some(State::Withdrawn)) => {
                Outcome::Withdrawn
            }
            (State::Rejected, _) | (State::Superseded, Some(State::Rejected)) => Outcome::Rejected,
            (State::Superseded, _) => Outcome::Superseded,
            // Not reachable from a hold; said as it is.
            (State::Submitted, _) => Outcome::Unchanged,
        }
    }
}

/// A nonconformity with the calibrations it concerns.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Traced {
    /// The nonconformity.
    pub nonconformity: Nonconformity,
    /// The calibrations made with the standard in its window, oldest first.
    pub calibrations: Vec<Affected>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::domain::standards::{
        CertificatePeriod, Parameters, StandardCertificate, StandardKind,
    };

    fn t(s: &str) -> Timestamp {
        Timestamp::parse(s).unwrap()
    }

    fn certificate(at: &str) -> StandardCertificate {
        StandardCertificate {
            number: "C-1".into(),
            issued_by: "PTB".into(),
            calibrated_at: t(at),
        }
    }

    fn stand() -> Standard {
        Standard {
            standard_id: "DH-1".into(),
            kind: StandardKind::TumbleStand,
            description: "dividing head".into(),
            manufacturer: None,
            model: None,
            serial: None,
            certificate: certificate("2026-06-01T00:00:00Z"),
            due_at: t("2027-06-01T00:00:00Z"),
            angle_std_arcsec: Some(2.0),
            gravity_m_s2: None,
            gravity_rel_std: None,
            temperature_std_c: None,
            degrees_of_freedom: None,
            traceability: "PTB".into(),
            earlier: vec![CertificatePeriod {
                certificate: certificate("2025-06-01T00:00:00Z"),
                due_at: t("2026-06-01T00:00:00Z"),
                parameters: Parameters {
                    angle_std_arcsec: Some(2.0),
                    gravity_m_s2: None,
                    gravity_rel_std: None,
                    temperature_std_c: None,
                    degrees_of_freedom: None,
                    traceability: "PTB".into(),
                },
                parameters_assumed: false,
            }],
            updated_at: t("2026-06-01T00:00:00Z"),
        }
    }

    fn body(found: &str, good: Option<&str>) -> NonconformityBody {
        NonconformityBody {
            found_at: found.into(),
            last_known_good_at: good.map(Into::into),
            reason: "indexing error 9″ at the 90° stop".into(),
        }
    }

    fn check(b: NonconformityBody) -> Result<Nonconformity, Invalid> {
        b.check(
            uuid::Uuid::from_u128(1),
            &stand(),
            t("2026-11-25T00:00:00Z"),
            Actor::service(),
        )
    }

    /// The window starts at the certificate in force at `found_at` — the
    /// current one, or an earlier one for a nonconformity found under it —
    /// or at the last known good date when one is given.
    #[test]
    fn the_window_starts_where_the_standard_was_last_good() {
        let now = check(body("2026-11-01T00:00:00Z", None)).unwrap();
        assert_eq!(now.window_from, t("2026-06-01T00:00:00Z"));
        let earlier = check(body("2026-03-01T00:00:00Z", None)).unwrap();
        assert_eq!(earlier.window_from, t("2025-06-01T00:00:00Z"));
        let checked = check(body("2026-11-01T00:00:00Z", Some("2026-09-15T00:00:00Z"))).unwrap();
        assert_eq!(checked.window_from, t("2026-09-15T00:00:00Z"));
    }

    #[test]
    fn bad_bodies_name_their_field() {
        for (b, pointer) in [
            (body("yesterday", None), "/found_at"),
            (body("2027-01-01T00:00:00Z", None), "/found_at"),
            (body("2024-01-01T00:00:00Z", None), "/found_at"),
            (
                body("2026-11-01T00:00:00Z", Some("2026-11-02T00:00:00Z")),
                "/last_known_good_at",
            ),
            (
                NonconformityBody {
                    reason: "  ".into(),
                    ..body("2026-11-01T00:00:00Z", None)
                },
                "/reason",
            ),
        ] {
            let e = check(b).unwrap_err();
            assert_eq!(e.errors[0].pointer, pointer, "{e:?}");
        }
    }

    #[test]
    fn outcomes_follow_the_states() {
        use State::*;
        assert_eq!(
            Outcome::of(Approved, UnderReview, None),
            Outcome::UnderReview
        );
        assert_eq!(Outcome::of(Submitted, Approved, None), Outcome::ReApproved);
        assert_eq!(Outcome::of(Approved, Withdrawn, None), Outcome::Withdrawn);
        assert_eq!(Outcome::of(Approved, Superseded, None), Outcome::Superseded);
        assert_eq!(Outcome::of(Withdrawn, Withdrawn, None), Outcome::Unchanged);
        assert_eq!(Outcome::of(UnderReview, Approved, None), Outcome::Unchanged);
        // Superseded: what stands for it decides.
        for (replacement, outcome) in [
            (UnderReview, Outcome::UnderReview),
            (Submitted, Outcome::Superseded),
            (Approved, Outcome::Superseded),
            (Withdrawn, Outcome::Withdrawn),
            (Rejected, Outcome::Rejected),
        ] {
            assert_eq!(
                Outcome::of(Submitted, Superseded, Some(replacement)),
                outcome,
                "{replacement:?}"
            );
        }
    }

    /// Before the window, clear; in it, held; after `found_at`, out of
    /// service under a certificate from before it, clear under one after.
    #[test]
    fn a_nonconformity_bears_on_tests_by_when_they_were_made() {
        let nc = check(body("2026-11-01T00:00:00Z", Some("2026-08-01T00:00:00Z"))).unwrap();
        let old = t("2026-06-01T00:00:00Z");
        let new = t("2026-11-10T00:00:00Z");
        for (at, certificate, want) in [
            ("2026-07-31T23:59:59Z", old, Bearing::Clear),
            ("2026-08-01T00:00:00Z", old, Bearing::Held),
            ("2026-11-01T00:00:00Z", old, Bearing::Held),
            ("2026-11-01T00:00:01Z", old, Bearing::OutOfService),
            (
                "2026-11-20T00:00:00Z",
                t("2026-11-01T00:00:00Z"),
                Bearing::OutOfService,
            ),
            ("2026-11-20T00:00:00Z", new, Bearing::Clear),
        ] {
            assert_eq!(bearing(&nc, certificate, t(at)), want, "{at}");
        }
        let why = out_of_service(&nc, t("2026-11-20T00:00:00Z"));
        assert!(
            why.contains("DH-1") && why.contains(&nc.id.to_string()),
            "{why}"
        );
        assert!(hold_reason(&[&nc]).contains("indexing error 9″"));
    }
}
