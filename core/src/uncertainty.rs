//! The uncertainty budget of each fused coefficient, GUM style: three
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
//!   Positions given only by gravity components have no angle to be wrong:
//!   `d_j = 0`.
//! * **gravity** (the relative uncertainty `u` of the gravity magnitude): a
//!   gravity `g(1 + ε)` scales every `a` by `1 + ε`, which changes a
//!   regressor of degree `n` by `n·ε` to first order, so the outputs by
//!   `ε·s_j` with `s_j = Σ_t deg_t·k_t·f_t(a_j)`; a common ε is fully
//!   correlated across positions: `gravity_t = u·|(A⁺·s)_t|`. For a linear
//!   model this is `u·|k_t|` on the scale terms and 0 on the bias.
//! * **combined** `= √(statistical² + indexing² + gravity²)`;
//!   **expanded** `U = coverage_factor × combined`.

use serde::Serialize;

use crate::estimate::finite;
use crate::term::TermMap;
use crate::tumble::TumbleTest;
use crate::{Error, Term};

/// One arcsecond in radians.
pub const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);

/// The tumble stand's systematic uncertainties (1σ).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stand {
    /// Indexing (angle) error of the dividing head, in radians.
    pub angle_std_rad: f64,
    /// Relative uncertainty of the local gravity magnitude.
    pub gravity_rel_std: f64,
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
    /// Root-sum-square of the three.
    pub combined: f64,
    /// `coverage_factor × combined`.
    pub expanded: f64,
}

/// The budget of every fused coefficient.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Uncertainty {
    /// The coverage factor `k` of the expanded uncertainties.
    pub coverage_factor: f64,
    /// Per term, in model order.
    pub terms: TermMap<TermBudget>,
}

impl Uncertainty {
    /// The expanded uncertainty of every term.
    pub fn expanded(&self) -> TermMap<f64> {
        TermMap(self.terms.iter().map(|(t, b)| (t, b.expanded)).collect())
    }
}

/// The budget of the fused coefficients `fused` (standard errors
/// `std_errors`) of `test`, for a stand and a coverage factor.
pub fn budget(
    test: &TumbleTest,
    fused: &TermMap<f64>,
    std_errors: &TermMap<f64>,
    stand: Stand,
    coverage_factor: f64,
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
    let mut out = Vec::with_capacity(terms.len());
    for (row, t) in terms.iter().enumerate() {
        let g_row = pinv.row(row);
        let indexing = stand.angle_std_rad
            * g_row
                .iter()
                .zip(&d)
                .map(|(a, dj)| (a * dj).powi(2))
                .sum::<f64>()
                .sqrt();
        let gravity = stand.gravity_rel_std
            * g_row
                .iter()
                .zip(&s)
                .map(|(a, sj)| a * sj)
                .sum::<f64>()
                .abs();
        let statistical = std_errors.get(*t).copied().unwrap_or(0.0);
        let combined = (statistical.powi(2) + indexing.powi(2) + gravity.powi(2)).sqrt();
        out.push((
            *t,
            TermBudget {
                statistical,
                indexing,
                gravity,
                combined,
                expanded: coverage_factor * combined,
            },
        ));
    }
    let expanded = TermMap(out.iter().map(|(t, b)| (*t, b.expanded)).collect());
    finite(&expanded, "expanded uncertainty")?;
    Ok(Uncertainty {
        coverage_factor,
        terms: TermMap(out),
    })
}
