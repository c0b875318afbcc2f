//! A stored triad's result document as the pages and documents read it
//! (what `crate::app::triad::StoredTriad` wrote): `b`, `S`, `T` with their
//! standard errors and expanded uncertainties, the decision, as found and
//! the fit.

use serde::Deserialize;

/// A stored triad's result document, as the page reads it.
#[derive(Debug, Clone, Deserialize)]
pub struct TriadDoc {
    /// The calibration.
    pub id: uuid::Uuid,
    /// The triad.
    pub sensor_id: String,
    /// The station.
    pub station_id: Option<String>,
    /// When performed.
    pub performed_at: String,
    /// When received.
    pub received_at: String,
    /// `known_orientations` or `gravity_magnitude`.
    pub method: String,
    /// The outputs' unit.
    pub unit: String,
    /// The temperature it was calibrated at, °C, when given.
    #[serde(default)]
    pub temperature_c: Option<f64>,
    /// `b`.
    pub b: [f64; 3],
    /// Its standard errors.
    pub b_std_errors: Option<[f64; 3]>,
    /// `S`.
    #[serde(rename = "S")]
    pub s: [[f64; 3]; 3],
    /// Its standard errors.
    #[serde(rename = "S_std_errors", default)]
    pub s_std_errors: Option<[[f64; 3]; 3]>,
    /// `T = S⁻¹`.
    #[serde(rename = "T")]
    pub t: [[f64; 3]; 3],
    /// Its standard errors.
    #[serde(rename = "T_std_errors", default)]
    pub t_std_errors: Option<[[f64; 3]; 3]>,
    /// Row norms of `S`.
    pub scale_factors: [f64; 3],
    /// xy, yz, zx.
    pub non_orthogonality_deg: [f64; 3],
    /// Per position.
    pub residuals: Vec<Vec<f64>>,
    /// The fit (unknown orientations).
    #[serde(default)]
    pub fit: Option<FitDoc>,
    /// Each axis's second-order coefficient.
    #[serde(rename = "S2", default)]
    pub s2: Option<[f64; 3]>,
    /// Their standard errors.
    #[serde(rename = "S2_std_errors", default)]
    pub s2_std_errors: Option<[f64; 3]>,
    /// Their expanded uncertainties.
    #[serde(rename = "S2_expanded", default)]
    pub s2_expanded: Option<[f64; 3]>,
    /// The model equation.
    pub model: String,
    /// The coverage factor a sensor type fixes (every triad stored before
    /// probabilities were stated has one); null otherwise.
    #[serde(default)]
    pub coverage_factor: Option<f64>,
    /// The coverage probability the expanded uncertainties were formed for.
    #[serde(default)]
    pub coverage_probability: Option<f64>,
    /// Each element's `u_c`, `ν_eff`, `k` and `p`, by name.
    #[serde(default)]
    pub coverage: Option<std::collections::BTreeMap<String, crate::domain::triad::ElementCoverage>>,
    /// `b`'s expanded uncertainties.
    #[serde(default)]
    pub b_expanded: Option<[f64; 3]>,
    /// `S`'s expanded uncertainties.
    #[serde(rename = "S_expanded", default)]
    pub s_expanded: Option<[[f64; 3]; 3]>,
    /// The decision against the sensor type's limits.
    #[serde(default)]
    pub decision: Option<DecisionDoc>,
    /// Why it was not judged.
    #[serde(default)]
    pub decision_note: Option<String>,
    /// As found against the previous triad.
    #[serde(default)]
    pub as_found: Option<AsFoundDoc>,
    /// The reference standards named, as used.
    #[serde(default)]
    pub standards: Vec<crate::domain::standards::UsedStandard>,
    /// The calibration this one supersedes, and why.
    #[serde(default)]
    pub supersedes: Option<crate::domain::review::Supersedes>,
    /// When the sensor is next due, when the triad was judged.
    #[serde(default)]
    pub due_at: Option<String>,
}

impl TriadDoc {
    /// Whether its elements have expanded uncertainties.
    pub fn expanded(&self) -> bool {
        self.coverage_factor.is_some() || self.coverage_probability.is_some()
    }

    /// How element `name`'s expanded uncertainty was formed: as the triad
    /// states it, or, for a triad stored before each element did, with its
    /// one coverage factor and the normal probability.
    pub fn covered(&self, name: &str) -> Option<super::result::Covered> {
        if let Some(c) = self.coverage.as_ref().and_then(|m| m.get(name)) {
            return Some(super::result::Covered {
                combined: c.combined,
                effective_dof: Some(c.effective_dof),
                k: c.coverage_factor,
                p: c.coverage_probability,
            });
        }
        let k = self.coverage_factor?;
        Some(super::result::Covered {
            combined: f64::NAN,
            effective_dof: None,
            k,
            p: accelcal_core::uncertainty::coverage_probability(k),
        })
    }

    /// How the expanded uncertainties were formed, as a method's sentence
    /// ends ([`super::coverage::coverage_statement`]); empty without.
    pub fn statement(&self) -> String {
        if !self.expanded() {
            return String::new();
        }
        super::coverage::stated(
            self.coverage_probability,
            self.coverage_factor,
            self.coverage.is_some(),
        )
    }
}

/// A triad's decision.
#[derive(Debug, Clone, Deserialize)]
pub struct DecisionDoc {
    /// `simple` or `guarded`.
    pub rule: String,
    /// The worst verdict.
    pub verdict: String,
    /// Per limited element.
    pub elements: std::collections::BTreeMap<String, ElementDecisionDoc>,
}

/// One element's decision.
#[derive(Debug, Clone, Deserialize)]
pub struct ElementDecisionDoc {
    /// The value.
    pub value: f64,
    /// Lower limit.
    pub min: Option<f64>,
    /// Upper limit.
    pub max: Option<f64>,
    /// Its expanded uncertainty.
    pub expanded: f64,
    /// Its verdict.
    pub verdict: String,
}

/// As found, as the page reads it.
#[derive(Debug, Clone, Deserialize)]
pub struct AsFoundDoc {
    /// The previous triad.
    pub previous_calibration_id: uuid::Uuid,
    /// The largest error, g.
    pub max_abs_error_g: f64,
}

/// The Levenberg–Marquardt fit's report.
#[derive(Debug, Clone, Deserialize)]
pub struct FitDoc {
    /// Evaluations.
    pub evaluations: usize,
    /// Why it stopped.
    pub stop: String,
    /// The directions' spread.
    pub spread: f64,
    /// Residuals' RMS, g.
    pub rms_g: f64,
    /// Residual degrees of freedom (absent in results stored before they
    /// were reported).
    #[serde(default)]
    pub degrees_of_freedom: usize,
}
