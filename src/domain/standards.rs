//! Reference standards: the tumble stands (dividing heads), reference
//! accelerometers, thermometers and local gravity values a laboratory
//! calibrates with, each with the certificate that calibrated it, when it
//! is due, the uncertainty parameters it contributes and a statement of its
//! traceability (issue 29).
//!
//! A standard's uncertainty parameter depends on its kind and is required
//! for it, refused for the others:
//!
//! | kind | parameter | meaning (1σ) |
//! |---|---|---|
//! | `tumble_stand` | `angle_std_arcsec` | indexing (angle) error of the head |
//! | `gravity` | `gravity_m_s2`, `gravity_rel_std` | the local value of g and its relative uncertainty |
//! | `thermometer` | `temperature_std_c` | the temperature reading's uncertainty |
//! | `reference_accelerometer` | — | (its certificate carries its own) |

pub use super::limits::MAX_DEGREES_OF_FREEDOM;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::field::{Errors, Invalid, Loc};
use super::limits::{
    GRAVITY_M_S2, MAX_ANGLE_STD_ARCSEC, MAX_DESCRIPTION_CHARS, MAX_FUTURE_SECONDS,
    MAX_GRAVITY_REL_STD, MAX_LABEL_CHARS, MAX_NOTES_CHARS, MAX_TEMPERATURE_STD_C,
};

use super::text::{Chars, check_str};
use super::timestamp::Timestamp;

/// What a reference standard is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum StandardKind {
    /// A tumble stand or dividing head.
    TumbleStand,
    /// A reference accelerometer.
    ReferenceAccelerometer,
    /// A thermometer.
    Thermometer,
    /// A local gravity value (a gravimetric survey's).
    Gravity,
}

impl StandardKind {
    /// The wire name.
    pub fn as_str(self) -> &'static str {
        match self {
            StandardKind::TumbleStand => "tumble_stand",
            StandardKind::ReferenceAccelerometer => "reference_accelerometer",
            StandardKind::Thermometer => "thermometer",
            StandardKind::Gravity => "gravity",
        }
    }
}

/// The certificate that calibrated a standard.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct StandardCertificate {
    /// The certificate's number (one line, at most 64 characters).
    #[schema(schema_with = crate::domain::schema::label)]
    pub number: String,
    /// The laboratory that issued it (one line, at most 256 characters).
    #[schema(schema_with = crate::domain::schema::description)]
    pub issued_by: String,
    /// When the standard was calibrated.
    pub calibrated_at: Timestamp,
}

/// The body of `PUT /v1/standards/{standard_id}`.
#[derive(Clone, Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct StandardBody {
    /// What it is.
    pub kind: StandardKind,
    /// What it is, in words (one line, at most 256 characters).
    #[schema(schema_with = crate::domain::schema::description)]
    pub description: String,
    /// Its manufacturer (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub manufacturer: Option<String>,
    /// Its model (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub model: Option<String>,
    /// Its serial number (one line, at most 64 characters).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::nullable_label)]
    pub serial: Option<String>,
    /// The certificate that calibrated it.
    pub certificate: StandardCertificate,
    /// When its calibration runs out: a calibration performed after this
    /// may not use it.
    pub due_at: Timestamp,
    /// A tumble stand's indexing error, arcseconds (1σ).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::angle_std_arcsec)]
    pub angle_std_arcsec: Option<f64>,
    /// A gravity value's g, in m/s².
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::gravity_m_s2)]
    pub gravity_m_s2: Option<f64>,
    /// A gravity value's relative uncertainty (1σ).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::gravity_rel_std)]
    pub gravity_rel_std: Option<f64>,
    /// A thermometer's uncertainty, °C (1σ).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::temperature_std_c)]
    pub temperature_std_c: Option<f64>,
    /// The degrees of freedom the certificate gives its uncertainty
    /// (1 to 1 000 000; absent: infinite, a Type B evaluation).
    #[serde(default)]
    #[schema(schema_with = crate::domain::schema::degrees_of_freedom)]
    pub degrees_of_freedom: Option<f64>,
    /// How its values are traceable to the SI (free text, at most 4096
    /// characters): the chain of calibrations up to a national institute.
    #[schema(schema_with = crate::domain::schema::notes)]
    pub traceability: String,
}

/// What a certificate of a standard states besides its dates: the
/// uncertainty parameters of the standard's kind, their degrees of freedom
/// when the certificate gives them, and the statement of traceability. A
/// test performed under a certificate is budgeted with that certificate's
/// parameters, whatever later certificates state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Parameters {
    /// A tumble stand's indexing error, arcseconds (1σ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_std_arcsec: Option<f64>,
    /// A gravity value's g, in m/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity_m_s2: Option<f64>,
    /// A gravity value's relative uncertainty (1σ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity_rel_std: Option<f64>,
    /// A thermometer's uncertainty, °C (1σ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_std_c: Option<f64>,
    /// The degrees of freedom of the uncertainty the certificate states
    /// (absent: infinite, as a Type B evaluation is taken without them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub degrees_of_freedom: Option<f64>,
    /// How its values are traceable to the SI.
    pub traceability: String,
}

/// A reference standard as stored and served.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(from = "stored::StandardStored")]
pub struct Standard {
    /// Its id.
    pub standard_id: String,
    /// What it is.
    pub kind: StandardKind,
    /// What it is, in words.
    pub description: String,
    /// Its manufacturer.
    pub manufacturer: Option<String>,
    /// Its model.
    pub model: Option<String>,
    /// Its serial number.
    pub serial: Option<String>,
    /// The certificate that calibrated it.
    pub certificate: StandardCertificate,
    /// When its calibration runs out.
    pub due_at: Timestamp,
    /// A tumble stand's indexing error, arcseconds (1σ), by its current
    /// certificate.
    pub angle_std_arcsec: Option<f64>,
    /// A gravity value's g, in m/s².
    pub gravity_m_s2: Option<f64>,
    /// A gravity value's relative uncertainty (1σ).
    pub gravity_rel_std: Option<f64>,
    /// A thermometer's uncertainty, °C (1σ).
    pub temperature_std_c: Option<f64>,
    /// The degrees of freedom of that uncertainty, when the certificate
    /// gives them (absent: infinite).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub degrees_of_freedom: Option<f64>,
    /// How its values are traceable to the SI.
    pub traceability: String,
    /// Its earlier certificates, newest first, each with the due date it
    /// set and the parameters it stated: kept when a `PUT` brings a new
    /// certificate, so that a test performed under an earlier one is still
    /// judged and budgeted by it.
    #[serde(default)]
    pub earlier: Vec<CertificatePeriod>,
    /// When it was last written.
    pub updated_at: Timestamp,
}

/// A certificate, the due date it set and the parameters it stated: the
/// period a standard was in calibration by it, `calibrated_at` to `due_at`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CertificatePeriod {
    /// The certificate.
    pub certificate: StandardCertificate,
    /// The due date it set.
    pub due_at: Timestamp,
    /// The parameters it stated.
    #[serde(flatten)]
    pub parameters: Parameters,
    /// True when the certificate's own parameters were not recorded — it
    /// was replaced before accelcal kept parameters by certificate (0.3) —
    /// and these are the standard's as they stood when it was first read
    /// since: an assumption the standard's record states rather than hides.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub parameters_assumed: bool,
}

impl Standard {
    /// The parameters its current certificate states.
    pub fn parameters(&self) -> Parameters {
        Parameters {
            angle_std_arcsec: self.angle_std_arcsec,
            gravity_m_s2: self.gravity_m_s2,
            gravity_rel_std: self.gravity_rel_std,
            temperature_std_c: self.temperature_std_c,
            degrees_of_freedom: self.degrees_of_freedom,
            traceability: self.traceability.clone(),
        }
    }

    /// Every certificate with its period and parameters, the current one
    /// first, then the earlier ones newest first.
    pub fn periods(&self) -> impl Iterator<Item = CertificatePeriod> + '_ {
        std::iter::once(CertificatePeriod {
            certificate: self.certificate.clone(),
            due_at: self.due_at,
            parameters: self.parameters(),
            parameters_assumed: false,
        })
        .chain(self.earlier.iter().cloned())
    }

    /// This standard as written over `before` (the record it replaces, if
    /// any): `before`'s certificate, with its parameters, joins the earlier
    /// ones when this one's differs.
    pub fn replacing(mut self, before: Option<Standard>) -> Standard {
        if let Some(b) = before {
            let parameters = b.parameters();
            self.earlier = b.earlier;
            if b.certificate != self.certificate {
                self.earlier.insert(
                    0,
                    CertificatePeriod {
                        certificate: b.certificate,
                        due_at: b.due_at,
                        parameters,
                        parameters_assumed: false,
                    },
                );
            }
        }
        self
    }

    /// The certificate period covering `at`, `calibrated_at ≤ at ≤ due_at`,
    /// of its certificate or an earlier one. `Err` says why there is none.
    pub fn in_calibration_at(&self, at: Timestamp) -> Result<CertificatePeriod, String> {
        if let Some(period) = self
            .periods()
            .find(|p| p.certificate.calibrated_at <= at && at <= p.due_at)
        {
            return Ok(period);
        }
        let first = self
            .earlier
            .last()
            .map_or(&self.certificate, |p| &p.certificate);
        Err(if at < first.calibrated_at {
            format!(
                "standard `{}` was first calibrated on {} (certificate {}); a test performed \
                 at {at} cannot have used it in calibration",
                self.standard_id, first.calibrated_at, first.number
            )
        } else if at > self.due_at {
            format!(
                "standard `{}` was due on {} (certificate {}); a test performed at {at} used it \
                 out of calibration — recalibrate it and record the new certificate \
                 (PUT /v1/standards/{}), then repeat the test",
                self.standard_id, self.due_at, self.certificate.number, self.standard_id
            )
        } else {
            format!(
                "standard `{}` was out of calibration at {at}: between the due date of one \
                 certificate and the calibration of the next; repeat the test",
                self.standard_id
            )
        })
    }
}

mod stored;

/// A standard as a calibration used it: in its role, with the certificate
/// it was in calibration by when the test was performed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct UsedStandard {
    /// `stand`, `thermometer` or `gravity`.
    pub role: String,
    /// Its id.
    pub standard_id: String,
    /// What it is.
    pub kind: StandardKind,
    /// What it is, in words.
    pub description: String,
    /// Its serial number.
    pub serial: Option<String>,
    /// The certificate in force when the test was performed.
    pub certificate: StandardCertificate,
    /// The due date that certificate set.
    pub due_at: Timestamp,
    /// What the certificate in force states: its parameters, their degrees
    /// of freedom and its statement of traceability.
    #[serde(flatten)]
    pub parameters: Parameters,
    /// True when the certificate's own parameters were not recorded and the
    /// standard's were assumed ([`CertificatePeriod::parameters_assumed`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub parameters_assumed: bool,
}

/// The kind a submission's `standards.<role>` must name.
pub fn kind_for_role(role: &str) -> Option<StandardKind> {
    match role {
        "stand" => Some(StandardKind::TumbleStand),
        "thermometer" => Some(StandardKind::Thermometer),
        "gravity" => Some(StandardKind::Gravity),
        _ => None,
    }
}

impl Standard {
    /// This standard used in `role` by a test performed at `at`: `Err`
    /// (why) when it is not of the role's kind or not in calibration then.
    pub fn used_as(&self, role: &str, at: Timestamp) -> Result<UsedStandard, String> {
        let wanted = kind_for_role(role);
        if wanted != Some(self.kind) {
            return Err(format!(
                "standard `{}` is a `{}`, not a `{}`",
                self.standard_id,
                self.kind.as_str(),
                wanted.map_or(role.to_owned(), |k| k.as_str().to_owned())
            ));
        }
        let p = self.in_calibration_at(at)?;
        Ok(UsedStandard {
            role: role.to_owned(),
            standard_id: self.standard_id.clone(),
            kind: self.kind,
            description: self.description.clone(),
            serial: self.serial.clone(),
            certificate: p.certificate,
            due_at: p.due_at,
            parameters: p.parameters,
            parameters_assumed: p.parameters_assumed,
        })
    }
}

/// One kind-specific parameter: its name, value, the kind that has it
/// and its accepted range.
struct Parameter {
    name: &'static str,
    value: Option<f64>,
    kind: StandardKind,
    range: std::ops::RangeInclusive<f64>,
    unit: &'static str,
}

impl StandardBody {
    /// Checks the body and makes the standard `standard_id` of it, written
    /// at `now`; every problem is reported.
    pub fn check(self, standard_id: String, now: Timestamp) -> Result<Standard, Invalid> {
        let root = Loc::Root;
        let mut errors = Errors::default();
        let mut line = |at: Loc, value: &str, max: usize| {
            if let Err(why) = check_str(value, max, Chars::Line) {
                errors.add(at, why);
            }
        };
        line(
            root.key("description"),
            &self.description,
            MAX_DESCRIPTION_CHARS,
        );
        for (name, value) in [
            ("manufacturer", &self.manufacturer),
            ("model", &self.model),
            ("serial", &self.serial),
        ] {
            if let Some(v) = value {
                line(root.key(name), v, MAX_LABEL_CHARS);
            }
        }
        let cert = root.key("certificate");
        line(
            cert.key("number"),
            &self.certificate.number,
            MAX_LABEL_CHARS,
        );
        line(
            cert.key("issued_by"),
            &self.certificate.issued_by,
            MAX_DESCRIPTION_CHARS,
        );
        if let Err(why) = check_str(&self.traceability, MAX_NOTES_CHARS, Chars::Text) {
            errors.add(root.key("traceability"), why);
        }
        let calibrated = self.certificate.calibrated_at;
        if calibrated > now.plus_seconds(MAX_FUTURE_SECONDS) {
            errors.add(
                cert.key("calibrated_at"),
                format!(
                    "is in the future ({calibrated}): a standard is calibrated before it is used"
                ),
            );
        }
        if self.due_at <= calibrated {
            errors.add(
                root.key("due_at"),
                format!(
                    "must be after the certificate's `calibrated_at` ({calibrated}), not {}",
                    self.due_at
                ),
            );
        }
        let parameters = [
            Parameter {
                name: "angle_std_arcsec",
                value: self.angle_std_arcsec,
                kind: StandardKind::TumbleStand,
                range: 0.0..=MAX_ANGLE_STD_ARCSEC,
                unit: " arcsec",
            },
            Parameter {
                name: "gravity_m_s2",
                value: self.gravity_m_s2,
                kind: StandardKind::Gravity,
                range: GRAVITY_M_S2,
                unit: " m/s²",
            },
            Parameter {
                name: "gravity_rel_std",
                value: self.gravity_rel_std,
                kind: StandardKind::Gravity,
                range: 0.0..=MAX_GRAVITY_REL_STD,
                unit: "",
            },
            Parameter {
                name: "temperature_std_c",
                value: self.temperature_std_c,
                kind: StandardKind::Thermometer,
                range: 0.0..=MAX_TEMPERATURE_STD_C,
                unit: " °C",
            },
        ];
        if let Some(nu) = self.degrees_of_freedom
            && !(1.0..=MAX_DEGREES_OF_FREEDOM).contains(&nu)
        {
            errors.add(
                root.key("degrees_of_freedom"),
                format!(
                    "must be from 1 to {MAX_DEGREES_OF_FREEDOM} (leave it out when the \
                     certificate gives none: infinite), not {nu}"
                ),
            );
        }
        if self.degrees_of_freedom.is_some() && self.kind == StandardKind::ReferenceAccelerometer {
            errors.add(
                root.key("degrees_of_freedom"),
                "belongs to a standard with an uncertainty parameter; a \
                 `reference_accelerometer` has none",
            );
        }
        for p in &parameters {
            let at = root.key(p.name);
            match (p.value, p.kind == self.kind) {
                (None, true) => errors.add(
                    at,
                    format!("is required for a `{}` standard", self.kind.as_str()),
                ),
                (Some(_), false) => errors.add(
                    at,
                    format!(
                        "belongs to a `{}` standard, not a `{}` one",
                        p.kind.as_str(),
                        self.kind.as_str()
                    ),
                ),
                (Some(v), true) if !p.range.contains(&v) => errors.add(
                    at,
                    format!(
                        "must be from {}{unit} to {}{unit}, not {v}",
                        p.range.start(),
                        p.range.end(),
                        unit = p.unit
                    ),
                ),
                _ => {}
            }
        }
        errors.finish(|| Standard {
            standard_id,
            kind: self.kind,
            description: self.description,
            manufacturer: self.manufacturer,
            model: self.model,
            serial: self.serial,
            certificate: self.certificate,
            due_at: self.due_at,
            angle_std_arcsec: self.angle_std_arcsec,
            gravity_m_s2: self.gravity_m_s2,
            gravity_rel_std: self.gravity_rel_std,
            temperature_std_c: self.temperature_std_c,
            degrees_of_freedom: self.degrees_of_freedom,
            traceability: self.traceability,
            earlier: Vec::new(),
            updated_at: now,
        })
    }
}

#[cfg(test)]
mod tests;
