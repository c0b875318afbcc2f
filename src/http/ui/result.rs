//! A stored result document read back for the pages and the certificate.
//!
//! The pages render what was answered when the calibration was stored (its
//! result document, immutable), never a recomputation. Fields that later
//! versions added (`uncertainty`, `decision`, …) are optional, so documents
//! stored before them still render.

use accelcal_core::TermMap;
use serde::Deserialize;
use uuid::Uuid;

/// The versions of the method that computed a result.
#[derive(Debug, Clone, Deserialize)]
pub struct MethodDoc {
    /// accelcal's.
    pub accelcal: String,
    /// accelcal-core's.
    pub core: String,
}

impl MethodDoc {
    /// "accelcal 0.2.0 (core 0.2.0)", or what to say when it was not recorded.
    pub fn describe(method: Option<&MethodDoc>) -> String {
        match method {
            Some(m) => format!("accelcal {} (core {})", m.accelcal, m.core),
            None => "not recorded (computed before accelcal 0.2.0)".to_owned(),
        }
    }
}

/// One position, resolved.
#[derive(Debug, Clone, Deserialize)]
pub struct PositionDoc {
    /// Gravity components in g.
    pub a: [f64; 3],
    /// The angle, when given.
    #[serde(default)]
    pub angle_deg: Option<f64>,
    /// Its label.
    #[serde(default)]
    pub label: Option<String>,
}

impl PositionDoc {
    /// A short name: the label, else the angle, else the components.
    pub fn name(&self, index: usize) -> String {
        match (&self.label, self.angle_deg) {
            (Some(l), _) => l.clone(),
            (None, Some(deg)) => format!("{deg}°"),
            (None, None) => format!(
                "#{} ({}, {}, {})",
                index + 1,
                self.a[0],
                self.a[1],
                self.a[2]
            ),
        }
    }
}

/// The stand a submission declared.
#[derive(Debug, Clone, Deserialize)]
pub struct StandDoc {
    /// Its id.
    #[serde(default)]
    pub id: Option<String>,
    /// Indexing error (1σ), arcseconds.
    pub angle_std_arcsec: f64,
    /// Relative uncertainty of gravity.
    pub gravity_rel_std: f64,
}

/// One run's identification.
#[derive(Debug, Clone, Deserialize)]
pub struct RunDoc {
    /// Coefficients.
    pub coefficients: TermMap<f64>,
    /// Standard errors (none without spare positions).
    #[serde(default)]
    pub std_errors: Option<TermMap<f64>>,
    /// Residual per position.
    pub residuals: Vec<f64>,
    /// Their root mean square.
    pub residual_rms: f64,
    /// Degrees of freedom.
    pub dof: usize,
}

/// The plain mean of the runs.
#[derive(Debug, Clone, Deserialize)]
pub struct MeanDoc {
    /// Eq. 1.
    pub coefficients: TermMap<f64>,
    /// Eq. 8 about the mean (null for a single run).
    #[serde(default)]
    pub dispersion: Option<TermMap<f64>>,
}

/// One fusion batch.
#[derive(Debug, Clone, Deserialize)]
pub struct BatchDoc {
    /// Its runs (0-based).
    pub runs: Vec<usize>,
}

/// The batch-estimation fusion.
#[derive(Debug, Clone, Deserialize)]
pub struct FusedDoc {
    /// The batches.
    pub batches: Vec<BatchDoc>,
    /// Fused values.
    pub coefficients: TermMap<f64>,
    /// Their standard errors.
    pub std_errors: TermMap<f64>,
    /// Eq. 8 about the fused values (null for a single run).
    #[serde(default)]
    pub dispersion: Option<TermMap<f64>>,
    /// Why there are no batches (a single run).
    #[serde(default)]
    pub note: Option<String>,
}

/// One coefficient's budget.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct BudgetDoc {
    /// Fused standard error.
    pub statistical: f64,
    /// From the stand's indexing error.
    pub indexing: f64,
    /// From gravity.
    pub gravity: f64,
    /// From the model's lack of fit (absent before it existed).
    #[serde(default)]
    pub model: f64,
    /// Root-sum-square.
    pub combined: f64,
    /// Its effective degrees of freedom (null: infinite; absent before
    /// they were stated).
    #[serde(default)]
    pub effective_dof: Option<u64>,
    /// Its coverage factor (absent before each term stated its own).
    #[serde(default)]
    pub coverage_factor: Option<f64>,
    /// Its coverage probability (likewise).
    #[serde(default)]
    pub coverage_probability: Option<f64>,
    /// Expanded.
    pub expanded: f64,
}

/// How an expanded uncertainty was formed, as a certificate states it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covered {
    /// The combined standard uncertainty.
    pub combined: f64,
    /// Its effective degrees of freedom: `Some(None)` infinite, `None` not
    /// stated (a result computed before they were).
    pub effective_dof: Option<Option<u64>>,
    /// `k`.
    pub k: f64,
    /// `p`; for a result computed before probabilities were stated, the
    /// normal distribution's for `k`.
    pub p: f64,
}

impl BudgetDoc {
    /// This term's coverage, within a budget that held `fixed` (the
    /// document's global factor, for results computed before each term
    /// stated its own).
    pub fn covered(&self, fixed: Option<f64>) -> Covered {
        match (self.coverage_factor, self.coverage_probability) {
            (Some(k), Some(p)) => Covered {
                combined: self.combined,
                effective_dof: Some(self.effective_dof),
                k,
                p,
            },
            _ => {
                let k = fixed.unwrap_or(2.0);
                Covered {
                    combined: self.combined,
                    effective_dof: None,
                    k,
                    p: accelcal_core::uncertainty::coverage_probability(k),
                }
            }
        }
    }
}

/// The uncertainty budget.
#[derive(Debug, Clone, Deserialize)]
pub struct UncertaintyDoc {
    /// The fixed coverage factor (a sensor type's; every result computed
    /// before probabilities were stated has one); null otherwise.
    #[serde(default)]
    pub coverage_factor: Option<f64>,
    /// The stated coverage probability; null when the factor is fixed.
    #[serde(default)]
    pub coverage_probability: Option<f64>,
    /// Per coefficient.
    pub terms: TermMap<BudgetDoc>,
}

impl UncertaintyDoc {
    /// The coverage of term `t`'s expanded uncertainty.
    pub fn covered(&self, t: accelcal_core::Term) -> Option<Covered> {
        self.terms.get(t).map(|b| b.covered(self.coverage_factor))
    }
}

/// One term's decision.
#[derive(Debug, Clone, Deserialize)]
pub struct TermDecisionDoc {
    /// The fused value.
    pub value: f64,
    /// Lower limit.
    #[serde(default)]
    pub min: Option<f64>,
    /// Upper limit.
    #[serde(default)]
    pub max: Option<f64>,
    /// Expanded uncertainty.
    pub expanded: f64,
    /// Its verdict.
    pub verdict: String,
}

/// The decision against the sensor type's limits.
#[derive(Debug, Clone, Deserialize)]
pub struct DecisionDoc {
    /// `simple` or `guarded`.
    pub rule: String,
    /// `pass`, `conditional` or `fail`.
    pub verdict: String,
    /// Per limited term.
    pub terms: TermMap<TermDecisionDoc>,
}

/// The error at one position with the previous coefficients.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct PositionErrorDoc {
    /// In output units.
    pub error_output: f64,
    /// In g.
    pub error_g: f64,
}

/// As found.
#[derive(Debug, Clone, Deserialize)]
pub struct AsFoundDoc {
    /// The previous calibration.
    pub previous_calibration_id: Uuid,
    /// Per position.
    pub positions: Vec<PositionErrorDoc>,
    /// Largest |error_g|.
    pub max_abs_error_g: f64,
}

/// One coefficient's temperature sensitivity.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct SensitivityDoc {
    /// Slope per kelvin.
    pub per_kelvin: f64,
    /// Its standard error.
    #[serde(default)]
    pub std_error: Option<f64>,
    /// Mean run temperature.
    pub reference_c: f64,
    /// The fit there.
    pub value_at_reference: f64,
}

/// A quality warning.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum WarningDoc {
    /// The design barely separates these terms.
    IllConditioned {
        /// Condition number.
        condition_number: f64,
        /// The terms.
        terms: Vec<String>,
    },
    /// The residuals exceed what the pure error explains.
    LackOfFit {
        /// The statistic.
        f: f64,
        /// Its degrees of freedom.
        df1: usize,
        /// Its degrees of freedom.
        df2: usize,
        /// Its p-value.
        p_value: f64,
        /// The pooled pure error.
        pure_error_std: f64,
        /// The root of the lack-of-fit mean square.
        lack_of_fit_std: f64,
    },
    /// A run scatters significantly more than the others (an F test on the
    /// pure error or the residuals; results computed before the F tests
    /// hold the RMS and the median instead).
    NoisyRun {
        /// Run index (0-based).
        run: usize,
        /// The statistic.
        #[serde(default)]
        f: Option<f64>,
        /// Its p-value.
        #[serde(default)]
        p_value: Option<f64>,
        /// `pure_error` or `residual` (results before hold the residual
        /// test without saying so).
        #[serde(default)]
        test: Option<String>,
        /// `s_j` of the residuals.
        #[serde(default)]
        residual_std: Option<f64>,
        /// `s_(−j)` of the residuals.
        #[serde(default)]
        others_residual_std: Option<f64>,
        /// `s_pe,j`.
        #[serde(default)]
        pure_error_std: Option<f64>,
        /// `s_pe,(−j)`.
        #[serde(default)]
        others_pure_error_std: Option<f64>,
        /// Former: its residual RMS.
        #[serde(default)]
        residual_rms: Option<f64>,
        /// Former: the median.
        #[serde(default)]
        median_residual_rms: Option<f64>,
    },
    /// A batch agrees better than its runs' own standard errors allow.
    ImplausiblyConsistentBatch {
        /// Batch index (0-based).
        batch: usize,
        /// The coefficient.
        term: String,
        /// The batch's deviation.
        std: f64,
        /// The floor its weight used.
        floor: f64,
    },
    /// A term outside the model would explain the data significantly better.
    UnmodelledTerm {
        /// The term.
        term: String,
        /// The statistic.
        f: f64,
        /// Its p-value.
        p_value: f64,
    },
}

/// The lack-of-fit test as stored.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum LackOfFitDoc {
    /// Computed.
    Tested {
        /// The statistic.
        f: f64,
        /// Its degrees of freedom.
        df1: usize,
        /// Its degrees of freedom.
        df2: usize,
        /// Its p-value.
        p_value: f64,
        /// The level.
        alpha: f64,
    },
    /// Not computed.
    NotTested {
        /// Why.
        reason: String,
    },
}

/// Quality flags.
#[derive(Debug, Clone, Deserialize)]
pub struct QualityDoc {
    /// The lack-of-fit test (absent before it existed).
    #[serde(default)]
    pub lack_of_fit: Option<LackOfFitDoc>,
    /// The warnings.
    pub warnings: Vec<WarningDoc>,
}

/// A stored result document.
#[derive(Debug, Clone, Deserialize)]
pub struct ResultDoc {
    /// The method's versions (absent before accelcal 0.2.0).
    #[serde(default)]
    pub method: Option<MethodDoc>,
    /// Calibration id.
    pub id: Uuid,
    /// The sensor.
    pub sensor_id: String,
    /// The station.
    #[serde(default)]
    pub station_id: Option<String>,
    /// When performed (canonical text).
    pub performed_at: String,
    /// When received.
    pub received_at: String,
    /// Output unit.
    pub unit: String,
    /// Model terms.
    pub model: Vec<String>,
    /// Mount.
    pub mount: String,
    /// Fusion batches.
    pub batches: usize,
    /// Notes.
    #[serde(default)]
    pub notes: Option<String>,
    /// Positions.
    pub positions: Vec<PositionDoc>,
    /// The sensor type in force.
    #[serde(default)]
    pub sensor_type: Option<String>,
    /// The stand.
    #[serde(default)]
    pub stand: Option<StandDoc>,
    /// The reference standards used, each with its certificate then.
    #[serde(default)]
    pub standards: Vec<crate::domain::standards::UsedStandard>,
    /// When the laboratory received the item.
    #[serde(default)]
    pub item_received_at: Option<String>,
    /// The item's condition on receipt.
    #[serde(default)]
    pub item_condition: Option<String>,
    /// Run temperatures.
    #[serde(default)]
    pub temperatures_c: Option<Vec<f64>>,
    /// The calibration this one supersedes, and why.
    #[serde(default)]
    pub supersedes: Option<crate::domain::review::Supersedes>,
    /// Condition number of the design.
    pub condition_number: f64,
    /// Per run.
    pub runs: Vec<RunDoc>,
    /// The plain mean.
    pub mean: MeanDoc,
    /// The fusion.
    pub fused: FusedDoc,
    /// The uncertainty budget.
    #[serde(default)]
    pub uncertainty: Option<UncertaintyDoc>,
    /// The decision.
    #[serde(default)]
    pub decision: Option<DecisionDoc>,
    /// As found.
    #[serde(default)]
    pub as_found: Option<AsFoundDoc>,
    /// Due date.
    #[serde(default)]
    pub due_at: Option<String>,
    /// Temperature sensitivity.
    #[serde(default)]
    pub temperature: Option<TermMap<SensitivityDoc>>,
    /// Quality flags.
    #[serde(default)]
    pub quality: Option<QualityDoc>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_method_is_described_or_said_to_be_unrecorded() {
        let m = MethodDoc {
            accelcal: "0.2.0".into(),
            core: "0.3.1".into(),
        };
        assert_eq!(MethodDoc::describe(Some(&m)), "accelcal 0.2.0 (core 0.3.1)");
        assert_eq!(
            MethodDoc::describe(None),
            "not recorded (computed before accelcal 0.2.0)"
        );
    }
}
