//! The uncertainty budget of each fused coefficient, GUM style: four
//! components, combined in quadrature and expanded by a coverage factor.
//!
//! With `A` the design (one row per position), `A⁺ = (AᵀA)⁻¹Aᵀ` its
//! pseudo-inverse and `k` the fused coefficients:
//!
//! * **statistical**: the fused standard error (batch-estimation fusion).
//! * **indexing** (the stand's angle error σ_θ, 1σ, in radians): an error δ_j
//!   of the dividing head at position `j` changes the output by `d_j·δ_j`,
//!   with `d_j = ∂(Σ_t k_t f_t(a(θ)))/∂θ` at `θ_j` — the gradient of the
//!   model in `a` dotted with the mount's `da/dθ`. The fit carries it into
//!   the coefficients through `G = A⁺·D`, `D = diag(d)`; independent errors
//!   of σ_θ at every position give `indexing_t = σ_θ·√(Σ_j G_tj²)`.
//!   A position given by its gravity vector `a_j` instead is perturbed by an
//!   independent small rotation `ω_j` with each of its three components of
//!   standard deviation σ_θ, so `δa_j = ω_j × a_j`. The coefficients are
//!   those of the run-averaged fit `c = (AᵀA)⁻¹Aᵀx̃` (residuals `r̃`); a
//!   change `δA` of row `j` changes them by the full first-order
//!   derivative, residual term included,
//!   `δc = (AᵀA)⁻¹(δAᵀ·r̃ − Aᵀ·δA·c) = (AᵀA)⁻¹·g·r̃_j − A⁺_{·j}·(g·c)` with
//!   `g_t = ∇f_t(a_j)·δa_j`, and such positions add
//!   `σ_θ²·Σ_j Σ_{e ∈ {x,y,z}} (δc_t at δa_j = e × a_j)²` to `indexing_t²`.
//! * **gravity** (the relative uncertainty `u` of the gravity magnitude): a
//!   gravity `g(1 + ε)` scales every `a` by `1 + ε`, which changes a
//!   regressor of degree `n` by `n·ε` to first order, so the outputs by
//!   `ε·s_j` with `s_j = Σ_t deg_t·k_t·f_t(a_j)`; a common ε is fully
//!   correlated across positions: `gravity_t = u·|(A⁺·s)_t|`. For a linear
//!   model this is `u·|k_t|` on the scale terms and 0 on the bias.
//! * **model**: the standard error of the fit to the run-averaged values
//!   when lack of fit is flagged, 0 otherwise
//!   ([`crate::adequacy::model_uncertainty`]).
//! * **combined** `= √(statistical² + indexing² + gravity² + model²)`;
//!   **expanded** `U = k × combined`, with `k` from the effective degrees of
//!   freedom of the four ([`crate::coverage`]): the statistical component's
//!   are the fused standard error's (`FusedEstimate::dof`), the model
//!   component's `P − p` of the run-averaged fit (positions less terms),
//!   and the stand's (indexing, gravity) infinite unless its certificate
//!   states them ([`Stand`]).

use serde::Serialize;

use crate::coverage::{Coverage, effective_dof};
use crate::estimate::finite;
use crate::fusion::scaled_norm;
use crate::term::TermMap;
use crate::tumble::TumbleTest;
use crate::{Error, Term};

/// One arcsecond in radians.
pub const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);

/// The tumble stand's systematic uncertainties (1σ), each with the degrees
/// of freedom its certificate states (`None`: infinite, a Type B
/// evaluation with no stated degrees of freedom).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stand {
    /// Indexing (angle) error of the dividing head, in radians.
    pub angle_std_rad: f64,
    /// Relative uncertainty of the local gravity magnitude.
    pub gravity_rel_std: f64,
    /// The indexing error's degrees of freedom.
    pub angle_dof: Option<f64>,
    /// The gravity value's degrees of freedom.
    pub gravity_dof: Option<f64>,
}

/// The degrees of freedom of each component of a budget; `null` (`None`)
/// where infinite.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ComponentDof {
    /// Of the statistical component.
    pub statistical: Option<f64>,
    /// Of the indexing component.
    pub indexing: Option<f64>,
    /// Of the gravity component.
    pub gravity: Option<f64>,
    /// Of the model component.
    pub model: Option<f64>,
}

/// The budget of one coefficient, in the coefficient's unit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TermBudget {
    /// The fused standard error.
    pub statistical: f64,
    /// From the stand's indexing error.
    pub indexing: f64,
    /// From the uncertainty of the gravity magnitude.
    pub gravity: f64,
    /// From the model's lack of fit.
    pub model: f64,
    /// Root-sum-square of the four.
    pub combined: f64,
    /// The degrees of freedom of each component.
    pub degrees_of_freedom: ComponentDof,
    /// Their effective degrees of freedom (Welch–Satterthwaite, truncated);
    /// `null` when infinite.
    pub effective_dof: Option<u64>,
    /// The coverage factor `k`.
    pub coverage_factor: f64,
    /// The coverage probability `p`.
    pub coverage_probability: f64,
    /// `k × combined`.
    pub expanded: f64,
}

impl TermBudget {
    /// The four components (statistical, indexing, gravity, model) with
    /// their degrees of freedom, combined in quadrature and expanded for
    /// `coverage` at their effective degrees of freedom.
    pub fn new(components: [f64; 4], dof: ComponentDof, coverage: Coverage) -> Self {
        let [statistical, indexing, gravity, model] = components;
        let combined =
            (statistical.powi(2) + indexing.powi(2) + gravity.powi(2) + model.powi(2)).sqrt();
        let covered = coverage.at(effective_dof(&[
            (statistical, dof.statistical),
            (indexing, dof.indexing),
            (gravity, dof.gravity),
            (model, dof.model),
        ]));
        TermBudget {
            statistical,
            indexing,
            gravity,
            model,
            combined,
            degrees_of_freedom: dof,
            effective_dof: covered.effective_dof,
            coverage_factor: covered.factor,
            coverage_probability: covered.probability,
            expanded: covered.factor * combined,
        }
    }
}

/// The budget of every fused coefficient.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Uncertainty {
    /// What the expanded uncertainties hold fixed: the coverage
    /// probability (each term's `k` then follows from its effective degrees
    /// of freedom) or the coverage factor.
    #[serde(flatten, serialize_with = "stated")]
    pub coverage: Coverage,
    /// Per term, in model order.
    pub terms: TermMap<TermBudget>,
}

/// `coverage` as the two fields a budget states, the one not fixed `null`:
/// `{"coverage_probability": 0.9545, "coverage_factor": null}`.
pub fn stated<S: serde::Serializer>(coverage: &Coverage, s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let (p, k) = match *coverage {
        Coverage::Probability(p) => (Some(p), None),
        Coverage::Factor(k) => (None, Some(k)),
    };
    let mut map = s.serialize_map(Some(2))?;
    map.serialize_entry("coverage_probability", &p)?;
    map.serialize_entry("coverage_factor", &k)?;
    map.end()
}

impl Uncertainty {
    /// The expanded uncertainty of every term.
    pub fn expanded(&self) -> TermMap<f64> {
        TermMap(self.terms.iter().map(|(t, b)| (t, b.expanded)).collect())
    }
}

/// `e × a` for the unit axis `e` (0, 1, 2) and a vector `a`.
fn cross_axis(e: usize, a: [f64; 3]) -> [f64; 3] {
    match e {
        0 => [0.0, -a[2], a[1]],
        1 => [a[2], 0.0, -a[0]],
        _ => [-a[1], a[0], 0.0],
    }
}

/// Per term, every `δc_t` (per radian of σ_θ) of the positions given by
/// gravity vectors, three per position (see the module doc).
fn explicit_indexing(test: &TumbleTest) -> Vec<Vec<f64>> {
    let design = test.design();
    let terms = design.model().terms();
    let mut changes = vec![Vec::new(); terms.len()];
    let explicit: Vec<usize> = (0..test.positions().len())
        .filter(|j| test.positions()[*j].rotation.is_none())
        .collect();
    if explicit.is_empty() {
        return changes;
    }
    let fit = test.averaged_fit();
    let c: Vec<f64> = fit.coefficients.iter().map(|(_, v)| *v).collect();
    let gram_inv = design.inverse_gram();
    let pinv = design.pseudo_inverse();
    for j in explicit {
        let a = test.positions()[j].a;
        for e in 0..3 {
            let da = cross_axis(e, a.to_array());
            let g: Vec<f64> = terms
                .iter()
                .map(|t| {
                    let grad = t.gradient(&a);
                    grad[0] * da[0] + grad[1] * da[1] + grad[2] * da[2]
                })
                .collect();
            let gc: f64 = g.iter().zip(&c).map(|(x, y)| x * y).sum();
            for (k, dcs) in changes.iter_mut().enumerate() {
                let first: f64 = (0..terms.len()).map(|l| gram_inv[(k, l)] * g[l]).sum();
                dcs.push(first * fit.residuals[j] - pinv[(k, j)] * gc);
            }
        }
    }
    changes
}

/// The coverage probability of an expanded uncertainty with coverage
/// factor `k` when the measurand's distribution is normal (GUM G.1.3):
///
/// ```text
/// p(k) = P(|X − μ| ≤ k·σ) = erf(k / √2)
/// ```
///
/// so `p(1) ≈ 0.6827`, `p(2) ≈ 0.9545`, `p(3) ≈ 0.9973`.
pub fn coverage_probability(k: f64) -> f64 {
    statrs::function::erf::erf(k / std::f64::consts::SQRT_2)
}

/// The budget of the fused coefficients `fused` (standard errors
/// `std_errors` on `dof` degrees of freedom, per term) of `test`, for a
/// stand and a coverage, with each term's `model` component (none for a
/// term `model` does not list).
pub fn budget(
    test: &TumbleTest,
    fused: &TermMap<f64>,
    (std_errors, dof): (&TermMap<f64>, &TermMap<f64>),
    stand: Stand,
    coverage: Coverage,
    model: &TermMap<f64>,
) -> Result<Uncertainty, Error> {
    let design = test.design();
    let terms = design.model().terms();
    let pinv = design.pseudo_inverse();
    let coefficient = |t: Term| fused.get(t).copied().unwrap_or(0.0);
    // d_j: the model's sensitivity to the angle at position j.
    let d: Vec<f64> = test
        .positions()
        .iter()
        .map(|p| match p.rotation {
            None => 0.0,
            Some(r) => {
                let da = r.mount.derivative(r.angle_deg).to_array();
                terms
                    .iter()
                    .map(|t| {
                        let g = t.gradient(&p.a);
                        coefficient(*t) * (g[0] * da[0] + g[1] * da[1] + g[2] * da[2])
                    })
                    .sum()
            }
        })
        .collect();
    // s_j: the outputs' first-order change per unit relative change of g.
    let s: Vec<f64> = test
        .positions()
        .iter()
        .map(|p| {
            terms
                .iter()
                .map(|t| f64::from(t.degree()) * coefficient(*t) * t.regressor(&p.a))
                .sum()
        })
        .collect();
    let explicit = explicit_indexing(test);
    // The run-averaged fit's residual degrees of freedom: P − p.
    let model_dof = test.positions().len().saturating_sub(terms.len()) as f64;
    let mut out = Vec::with_capacity(terms.len());
    for (row, t) in terms.iter().enumerate() {
        let g_row = pinv.row(row);
        let angles = g_row.iter().zip(&d).map(|(a, dj)| a * dj);
        let indexing =
            stand.angle_std_rad * scaled_norm(angles.chain(explicit[row].iter().copied()));
        let gravity = stand.gravity_rel_std
            * g_row
                .iter()
                .zip(&s)
                .map(|(a, sj)| a * sj)
                .sum::<f64>()
                .abs();
        let statistical = std_errors.get(*t).copied().unwrap_or(0.0);
        let model = model.get(*t).copied().unwrap_or(0.0);
        let dof = ComponentDof {
            statistical: dof.get(*t).copied(),
            indexing: stand.angle_dof,
            gravity: stand.gravity_dof,
            model: Some(model_dof),
        };
        out.push((
            *t,
            TermBudget::new([statistical, indexing, gravity, model], dof, coverage),
        ));
    }
    let expanded = TermMap(out.iter().map(|(t, b)| (*t, b.expanded)).collect());
    finite(&expanded, "expanded uncertainty")?;
    Ok(Uncertainty {
        coverage,
        terms: TermMap(out),
    })
}
