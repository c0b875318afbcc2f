//! What a triad calibration answers ([`TriadResult`]): `b`, `S`, `T` with
//! standard errors and expanded uncertainties per element, the fit or the
//! per-axis results, the decision against a sensor type's limits
//! ([`decide_triad`]) and as found against the previous triad
//! ([`as_found`]).

use super::*;

pub(super) fn mean(samples: &[[f64; 3]]) -> [f64; 3] {
    let n = samples.len().max(1) as f64;
    let mut m = [0.0; 3];
    for u in samples {
        for k in 0..3 {
            m[k] += u[k] / n;
        }
    }
    m
}

/// One axis's single-axis identification within a triad.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct AxisResult {
    /// `x`, `y` or `z`.
    pub axis: &'static str,
    /// The arithmetic mean across runs with eq. 8 dispersion.
    #[schema(value_type = Object)]
    pub mean: serde_json::Value,
    /// The batch-estimation fusion with eq. 8 dispersion.
    #[schema(value_type = Object)]
    pub fused: serde_json::Value,
    /// The axis's uncertainty budget, as a single-axis calibration's
    /// (standard error, stand indexing, gravity, model; expanded with
    /// `coverage_factor`).
    #[schema(value_type = Object)]
    pub uncertainty: serde_json::Value,
    /// The single-axis method's quality warnings for the axis.
    #[schema(value_type = Object)]
    pub quality: serde_json::Value,
}

/// Levenberg–Marquardt's report.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct FitReport {
    /// Residual evaluations made.
    pub evaluations: usize,
    /// Why it stopped: `converged`, `orthogonal` or `residuals_zero`.
    pub stop: &'static str,
    /// The directions' spread (reciprocal condition of the normalised
    /// Jacobian).
    pub spread: f64,
    /// The least spread accepted.
    pub min_spread: f64,
    /// Root mean square of the residuals, g.
    pub rms_g: f64,
    /// Residual degrees of freedom, positions − 9 (the standard errors rest
    /// on them; none with exactly nine).
    pub degrees_of_freedom: usize,
}

/// The elements of `S` that are zero by the frame convention of a triad
/// found from the gravity magnitude (the sensor's x axis and xy-plane
/// define the frame): `(row, column)` above the diagonal. Not measured,
/// so never judged.
pub const FIXED_BY_CONVENTION: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 2)];

/// `coverage` as [`accelcal_core::uncertainty::stated`] writes it, nothing
/// when there is none.
pub(super) fn stated<S: serde::Serializer>(
    coverage: &Option<Coverage>,
    s: S,
) -> Result<S::Ok, S::Error> {
    match coverage {
        Some(c) => accelcal_core::uncertainty::stated(c, s),
        None => serde::ser::SerializeMap::end(s.serialize_map(Some(0))?),
    }
}

/// How one element's expanded uncertainty was formed: its combined
/// standard uncertainty, effective degrees of freedom, coverage factor and
/// probability (Welch–Satterthwaite and Student's t).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ElementCoverage {
    /// The combined standard uncertainty `u_c`.
    pub combined: f64,
    /// Its effective degrees of freedom; null when infinite.
    pub effective_dof: Option<u64>,
    /// `k`.
    pub coverage_factor: f64,
    /// `p`.
    pub coverage_probability: f64,
}

impl From<&TermBudget> for ElementCoverage {
    fn from(b: &TermBudget) -> Self {
        ElementCoverage {
            combined: b.combined,
            effective_dof: b.effective_dof,
            coverage_factor: b.coverage_factor,
            coverage_probability: b.coverage_probability,
        }
    }
}

/// The uncertainty budget of a triad found from the gravity magnitude,
/// element by element ([`accelcal_core::gravity_budget`]).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct GravityUncertainty {
    /// What the expanded uncertainties hold fixed.
    #[serde(flatten, serialize_with = "accelcal_core::uncertainty::stated")]
    #[schema(value_type = crate::domain::schema::CoverageStated)]
    pub coverage: Coverage,
    /// The fit's residual degrees of freedom, which the statistical
    /// components rest on.
    pub degrees_of_freedom: usize,
    /// The relative uncertainty of the gravity magnitude used (1σ).
    pub gravity_rel_std: f64,
    /// Per element of `b` and of `S` on and below the diagonal (`b_x`,
    /// `S_yx`, …): statistical (the fit's standard error), indexing (0:
    /// the fit uses no orientation), gravity, model (0: the residuals'
    /// scatter holds any misfit), combined, expanded.
    #[schema(value_type = BTreeMap<String, Object>)]
    pub elements: BTreeMap<String, TermBudget>,
    /// The elements of `S` zero by the frame convention: not measured, not
    /// judged.
    pub fixed_by_convention: Vec<String>,
}

impl GravityUncertainty {
    pub(super) fn of(budget: &GravityBudget, gravity_rel_std: f64) -> Self {
        let mut elements = BTreeMap::new();
        for m in 0..3 {
            elements.insert(element(m, Slot::B), budget.b[m]);
            for k in 0..=m {
                elements.insert(element(m, Slot::S(k)), budget.s[m][k]);
            }
        }
        GravityUncertainty {
            coverage: budget.coverage,
            degrees_of_freedom: budget.degrees_of_freedom,
            gravity_rel_std,
            elements,
            fixed_by_convention: FIXED_BY_CONVENTION
                .iter()
                .map(|(m, k)| element(*m, Slot::S(*k)))
                .collect(),
        }
    }
}

/// One static interval of a recording.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct IntervalReport {
    /// Its start, s from the recording's start.
    pub start_s: f64,
    /// Its end, s.
    pub end_s: f64,
    /// Whether it is one of the positions.
    pub used: bool,
    /// Why not: `too_short`.
    pub rejected: Option<&'static str>,
    /// Its mean outputs.
    pub mean: [f64; 3],
}

/// What the detector did with a recording.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct DetectionReport {
    /// The parameters used.
    pub still_s: f64,
    /// The window, s.
    pub window_s: f64,
    /// The threshold multiple.
    pub threshold: f64,
    /// The shortest interval used, s.
    pub min_static_s: f64,
    /// The initial still period's variance (sum over the axes).
    pub still_variance: f64,
    /// The variance threshold.
    pub threshold_variance: f64,
    /// Every static interval found.
    pub intervals: Vec<IntervalReport>,
}

/// A triad's result (`POST /v1/identify/triad`).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TriadResult {
    /// `triad`.
    pub kind: &'static str,
    /// `known_orientations` or `gravity_magnitude`.
    pub method: &'static str,
    /// The echoed id.
    pub sensor_id: Option<String>,
    /// The outputs' unit.
    pub unit: String,
    /// The temperature it was calibrated at, °C, when the body gives
    /// temperatures: the mean of the runs' (of the static positions', of
    /// the recording's samples'), which all lie within 0.5 K of one
    /// another. What a temperature model combined from stored triads
    /// groups them by.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature_c: Option<f64>,
    /// `u = b + S g`.
    pub model: &'static str,
    /// How to compensate.
    pub compensation: &'static str,
    /// `b`, in the outputs' unit.
    pub b: [f64; 3],
    /// Its standard errors (null with exactly nine static positions).
    pub b_std_errors: Option<[f64; 3]>,
    /// `S`, rows by axis, in the outputs' unit per g.
    #[serde(rename = "S")]
    pub s: [[f64; 3]; 3],
    /// Its standard errors (known orientations).
    #[serde(rename = "S_std_errors", skip_serializing_if = "Option::is_none")]
    pub s_std_errors: Option<[[f64; 3]; 3]>,
    /// `T = S⁻¹`, g per output unit.
    #[serde(rename = "T")]
    pub t: [[f64; 3]; 3],
    /// Its standard errors (unknown orientations; null with exactly nine).
    #[serde(rename = "T_std_errors", skip_serializing_if = "Option::is_none")]
    pub t_std_errors: Option<[[f64; 3]; 3]>,
    /// With `second_order`: each axis's second-order coefficient `S2_m`
    /// (its `kii`), outputs' unit per g².
    #[serde(rename = "S2", skip_serializing_if = "Option::is_none")]
    pub s2: Option<[f64; 3]>,
    /// Their standard errors.
    #[serde(rename = "S2_std_errors", skip_serializing_if = "Option::is_none")]
    pub s2_std_errors: Option<[f64; 3]>,
    /// Their expanded uncertainties.
    #[serde(rename = "S2_expanded", skip_serializing_if = "Option::is_none")]
    pub s2_expanded: Option<[f64; 3]>,
    /// What the expanded uncertainties hold fixed, as two fields:
    /// `coverage_probability` (each element's coverage factor then follows
    /// from its effective degrees of freedom, `coverage`) or
    /// `coverage_factor` (a sensor type's fixed factor), the other null.
    /// Both absent without expanded uncertainties (the gravity magnitude
    /// with exactly nine positions).
    #[serde(flatten, serialize_with = "stated")]
    #[schema(value_type = crate::domain::schema::CoverageStated)]
    pub stated: Option<Coverage>,
    /// Each element's combined standard uncertainty, effective degrees of
    /// freedom, coverage factor and probability, by name (`b_x`, `S_yx`,
    /// `S2_z`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<BTreeMap<String, ElementCoverage>>)]
    pub coverage: Option<BTreeMap<String, ElementCoverage>>,
    /// `b`'s expanded uncertainties: known orientations, each axis's `k0`
    /// budget; the gravity magnitude, the fit's budget (`uncertainty`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub b_expanded: Option<[f64; 3]>,
    /// `S`'s expanded uncertainties: known orientations, each axis's `ki`,
    /// `kp`, `ko` budgets; the gravity magnitude, the fit's budget (0 above
    /// the diagonal, fixed by the frame convention).
    #[serde(rename = "S_expanded", skip_serializing_if = "Option::is_none")]
    pub s_expanded: Option<[[f64; 3]; 3]>,
    /// The gravity magnitude: the budget element by element (known
    /// orientations have theirs per axis, `axes[m].uncertainty`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<GravityUncertainty>,
    /// The nonconformities of its standards it was performed inside the
    /// windows of (a stored triad): it is stored under review.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub held_by: Vec<crate::domain::nonconformity::HeldBy>,
    /// Stored triads of a typed sensor: the decision against its limits,
    /// element by element.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decision: Option<TriadDecision>,
    /// Why a typed sensor's triad was not judged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decision_note: Option<String>,
    /// Stored triads: as found with the sensor's previous triad
    /// ([`as_found`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub as_found: Option<TriadAsFound>,
    /// Stored triads: the reference standards named, as the registry
    /// describes them (what traceability and the reverse trace read).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    #[schema(value_type = Vec<Object>)]
    pub standards: Vec<UsedStandard>,
    /// Why there is no `as_found` although there is a previous calibration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub as_found_note: Option<String>,
    /// Each position's mean outputs (what as found compensates).
    #[serde(skip)]
    pub means: Vec<[f64; 3]>,
    /// Known orientations: each position's gravity vector.
    #[serde(skip)]
    pub gravity: Option<Vec<[f64; 3]>>,
    /// Each axis's scale factor: the norm of its row of `S`.
    pub scale_factors: [f64; 3],
    /// How far each pair of sensitive axes is from perpendicular, degrees
    /// (`xy`, `yz`, `zx`: 90° minus the angle between their rows of `S`).
    pub non_orthogonality_deg: [f64; 3],
    /// Per position, the residual: known orientations, `ū − (b + S g)` per
    /// axis in the outputs' unit; unknown, `‖T (ū − b)‖ − 1` in g.
    pub residuals: Vec<Vec<f64>>,
    /// Known orientations: each axis's single-axis identification.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub axes: Option<Vec<AxisResult>>,
    /// Unknown orientations: the fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitReport>,
    /// Unknown orientations: each position's fitted gravity direction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub directions: Option<Vec<[f64; 3]>>,
    /// A recording: the static intervals.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detection: Option<DetectionReport>,
}

/// Where an axis's term sits in the triad.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// `b_m`.
    B,
    /// Row `m` of `S`, this column.
    S(usize),
    /// `S2_m`.
    S2,
}

/// Axis `m`'s terms and where each sits in the triad: `k0` in `b_m`,
/// `ki`, `kp`, `ko` in row `m` of `S` at columns `m`, `m + 1`, `m + 2`
/// (cyclically) — the single-axis model with
/// `(a_i, a_p, a_o) = (g_m, g_{m+1}, g_{m+2})` — and `kii` in `S2_m`.
pub fn row_terms(m: usize) -> [(Term, Slot); 5] {
    [
        (Term::K0, Slot::B),
        (Term::Ki, Slot::S(m)),
        (Term::Kp, Slot::S((m + 1) % 3)),
        (Term::Ko, Slot::S((m + 2) % 3)),
        (Term::Kii, Slot::S2),
    ]
}

/// A stored triad's decision against its sensor type's limits: each
/// axis's terms judged as a single-axis calibration's (its fused value and
/// expanded uncertainty), named by the element they are (`b_x` for the x
/// axis's `k0`, `S_xy` for its `kp`, …).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TriadDecision {
    /// The rule applied.
    #[schema(value_type = crate::domain::schema::RuleSchema)]
    pub rule: Rule,
    /// The worst verdict of the elements.
    #[schema(value_type = crate::domain::schema::VerdictSchema)]
    pub verdict: Verdict,
    /// Per limited element.
    #[schema(value_type = std::collections::BTreeMap<String, Object>)]
    pub elements: BTreeMap<String, TermDecision>,
}

/// The element name of axis `m`'s term in `slot` ([`row_terms`]).
pub fn element(m: usize, slot: Slot) -> String {
    match slot {
        Slot::B => format!("b_{}", AXES[m]),
        Slot::S(k) => format!("S_{}{}", AXES[m], AXES[k]),
        Slot::S2 => format!("S2_{}", AXES[m]),
    }
}

/// Judges a triad against `limits` (a sensor type's, per single-axis term)
/// with `rule`: each axis's `k0, ki, kp, ko` are its elements
/// ([`row_terms`]), each judged with its value and expanded uncertainty —
/// but for the elements of a triad from the gravity magnitude that are
/// zero by the frame convention ([`FIXED_BY_CONVENTION`]), which are not
/// measured. `None` without expanded uncertainties; `Err` names a limited
/// term a triad does not identify.
pub fn decide_triad(
    r: &TriadResult,
    rule: Rule,
    limits: &TermMap<Limit>,
) -> Result<Option<TriadDecision>, Term> {
    let (Some(b_u), Some(s_u)) = (r.b_expanded, r.s_expanded) else {
        return Ok(None);
    };
    let mut elements = BTreeMap::new();
    let mut verdict = Verdict::Pass;
    for m in 0..3 {
        let at = |slot: Slot, b: &[f64; 3], s: &[[f64; 3]; 3], s2: Option<&[f64; 3]>| match slot {
            Slot::B => Some(b[m]),
            Slot::S(k) => Some(s[m][k]),
            Slot::S2 => s2.map(|s2| s2[m]),
        };
        let terms = row_terms(m);
        let map = |b: &[f64; 3], s: &[[f64; 3]; 3], s2: Option<&[f64; 3]>| {
            TermMap(
                terms
                    .iter()
                    .filter_map(|(t, slot)| at(*slot, b, s, s2).map(|x| (*t, x)))
                    .collect(),
            )
        };
        let values = map(&r.b, &r.s, r.s2.as_ref());
        let expanded = map(&b_u, &s_u, r.s2_expanded.as_ref());
        let fixed = |t: Term| {
            r.method == GRAVITY_MAGNITUDE
                && terms.iter().any(|(term, slot)| {
                    *term == t
                        && matches!(slot, Slot::S(k) if FIXED_BY_CONVENTION.contains(&(m, *k)))
                })
        };
        let limits = TermMap(
            limits
                .iter()
                .filter(|(t, _)| !fixed(*t))
                .map(|(t, l)| (t, *l))
                .collect(),
        );
        let d = decide(rule, &limits, &values, &expanded)?;
        verdict = verdict.max(d.verdict);
        for (term, td) in d.terms.iter() {
            let slot = terms
                .iter()
                .find(|(t, _)| *t == term)
                .map_or(Slot::B, |(_, c)| *c);
            elements.insert(element(m, slot), *td);
        }
    }
    Ok(Some(TriadDecision {
        rule,
        verdict,
        elements,
    }))
}

/// As found: how far from the truth the previous calibration's `b` and
/// `S` put this test's positions.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TriadAsFound {
    /// The previous calibration.
    pub previous_calibration_id: uuid::Uuid,
    /// Per position, the error in g: with known orientations
    /// `S_prev⁻¹ (ū − b_prev) − g` per axis; with unknown ones
    /// `‖S_prev⁻¹ (ū − b_prev)‖ − 1`.
    pub positions: Vec<Vec<f64>>,
    /// The largest of them in magnitude, g.
    pub max_abs_error_g: f64,
}

/// As found of `r` with the previous triad `(b, S)` (calibration
/// `previous`): each position's mean outputs compensated with the previous
/// `b`, `S` (and `S2`), against the known gravity vector, or against a magnitude
/// of 1 g when the orientations were not known:
///
/// ```text
/// e_p = S_prev⁻¹ (ū_p − b_prev) − g_p            known orientations (3 components)
/// e_p = ‖S_prev⁻¹ (ū_p − b_prev)‖ − 1            unknown orientations
/// max_abs_error_g = max over p and components of |e_p|
/// ```
///
/// `None` when the previous `S` is singular.
pub fn as_found(r: &TriadResult, previous: uuid::Uuid, prev: &Triad) -> Option<TriadAsFound> {
    let positions: Vec<Vec<f64>> = r
        .means
        .iter()
        .enumerate()
        .map(|(p, u)| {
            let g = prev.compensate(*u).ok()?;
            Some(match &r.gravity {
                Some(known) => (0..3).map(|k| g[k] - known[p][k]).collect(),
                None => vec![g.iter().map(|x| x * x).sum::<f64>().sqrt() - 1.0],
            })
        })
        .collect::<Option<_>>()?;
    let max_abs_error_g = positions
        .iter()
        .flatten()
        .fold(0.0_f64, |m, e| m.max(e.abs()));
    Some(TriadAsFound {
        previous_calibration_id: previous,
        positions,
        max_abs_error_g,
    })
}

/// The method of a triad with known orientations.
pub const KNOWN_ORIENTATIONS: &str = "known_orientations";
/// The method of a triad found from the gravity magnitude.
pub const GRAVITY_MAGNITUDE: &str = "gravity_magnitude";

/// The model equation.
pub const MODEL: &str = "u = b + S g";
/// The compensation.
pub const COMPENSATION: &str = "g = T (u - b), T = S^-1";
/// The model with second-order terms.
pub const MODEL_SECOND_ORDER: &str = "u = b + S g + S2 * g^2 (S2_m g_m^2 on axis m)";
/// Its compensation.
pub const COMPENSATION_SECOND_ORDER: &str =
    "solve u = b + S g + S2 * g^2 for g by Newton's iteration from g = T (u - b), T = S^-1";
