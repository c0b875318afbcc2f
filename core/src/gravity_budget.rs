//! The uncertainty budget of a triad found from the gravity magnitude
//! ([`crate::gravity_fit`]), element by element of `b` and `S`, in the four
//! components of the single-axis budget ([`crate::uncertainty`]):
//!
//! * **statistical**: the fit's standard error — `b`'s from the Jacobian,
//!   `S`'s propagated from `T`'s full covariance (`dS = −S dT S`). Its `σ̂`
//!   is the residuals' own scatter, so a model short of the data already
//!   raises it;
//! * **indexing**: 0. The fit uses no orientation — only that gravity has
//!   the same magnitude in every position — so an error in where the triad
//!   was turned (by hand or on a stand) does not enter the result;
//! * **gravity** (the relative uncertainty `u` of the local gravity
//!   magnitude): the fit takes every position's specific force as 1 g. A
//!   gravity `g(1 + ε)` makes `‖T'(ū − b)‖ = 1 + ε` for the true `T'`, so
//!   `T' = (1 + ε) T`, `S' = S / (1 + ε)` and `b` is unchanged: to first
//!   order `gravity = u·|S_ij|` on `S` and 0 on `b` — the single-axis
//!   budget's `u·|k_t|` on the scale terms and 0 on the bias;
//! * **model**: 0, since `σ̂` holds any lack of fit (there are no repeated
//!   positions to tell pure error from it);
//! * **combined** and **expanded** as in the single-axis budget, the
//!   statistical component on the fit's `n − 9` residual degrees of
//!   freedom and the gravity component on its certificate's (infinite
//!   unless stated).
//!
//! `S`'s elements above the diagonal are zero by the frame convention (the
//! sensor's x axis and xy-plane define the frame): not measured, their
//! budget is zero. With exactly nine positions the fit has no degree of
//! freedom and no standard error, and there is no budget.

use serde::Serialize;

use crate::coverage::Coverage;
use crate::gravity_fit::GravityFit;
use crate::uncertainty::{ComponentDof, TermBudget};

/// The budget of a triad found from the gravity magnitude.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GravityBudget {
    /// What the expanded uncertainties hold fixed.
    #[serde(flatten, serialize_with = "crate::uncertainty::stated")]
    pub coverage: Coverage,
    /// The fit's residual degrees of freedom (`n − 9`), which the
    /// statistical components rest on.
    pub degrees_of_freedom: usize,
    /// Per element of `b`.
    pub b: [TermBudget; 3],
    /// Per element of `S`, rows by axis.
    pub s: [[TermBudget; 3]; 3],
}

/// The budget of `fit` for a gravity magnitude of relative uncertainty
/// `gravity_rel_std` (1σ) on `gravity_dof` degrees of freedom (`None`:
/// infinite) and a coverage; `None` without standard errors (exactly nine
/// positions).
pub fn budget(
    fit: &GravityFit,
    (gravity_rel_std, gravity_dof): (f64, Option<f64>),
    coverage: Coverage,
) -> Option<GravityBudget> {
    let (b_std, s_std) = (fit.bias_std?, fit.s_std?);
    let dof = ComponentDof {
        statistical: Some(fit.degrees_of_freedom as f64),
        indexing: None,
        gravity: gravity_dof,
        model: None,
    };
    let element = |statistical: f64, gravity: f64| {
        TermBudget::new([statistical, 0.0, gravity, 0.0], dof, coverage)
    };
    Some(GravityBudget {
        coverage,
        degrees_of_freedom: fit.degrees_of_freedom,
        b: [0, 1, 2].map(|m| element(b_std[m], 0.0)),
        s: [0, 1, 2]
            .map(|i| [0, 1, 2].map(|j| element(s_std[i][j], gravity_rel_std * fit.s[i][j].abs()))),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gravity_fit::fit;
    use crate::gravity_fit::tests::{directions, noisy, outputs, truth};

    #[test]
    fn the_components_combine_in_quadrature() {
        let f = fit(&noisy(12, 11, 1e-4, 13)).unwrap();
        let u = 3e-4;
        let got = budget(&f, (u, None), Coverage::Factor(2.0)).unwrap();
        assert_eq!(got.degrees_of_freedom, 3);
        let (b_std, s_std) = (f.bias_std.unwrap(), f.s_std.unwrap());
        for m in 0..3 {
            let e = got.b[m];
            assert_eq!(
                (e.statistical, e.indexing, e.gravity, e.model),
                (b_std[m], 0.0, 0.0, 0.0)
            );
            assert_eq!(e.combined, b_std[m]);
            assert_eq!(e.expanded, 2.0 * b_std[m]);
            for (k, e) in got.s[m].iter().enumerate() {
                let gravity = u * f.s[m][k].abs();
                assert_eq!(e.gravity, gravity);
                assert_eq!(e.statistical, s_std[m][k]);
                let combined = s_std[m][k].hypot(gravity);
                assert!((e.combined - combined).abs() <= 1e-15 * combined.max(1e-300));
                assert!((e.expanded - 2.0 * combined).abs() <= 2e-15 * combined.max(1e-300));
                if k > m {
                    assert_eq!(e.expanded, 0.0, "S{m}{k} is zero by the convention");
                }
            }
        }
        assert!(got.s[0][0].gravity > 0.0 && got.s[2][1].statistical > 0.0);
    }

    /// At a stated probability, `b` (statistical only, on the fit's three
    /// degrees of freedom) is expanded by Student's t on 3: scipy's
    /// `t.ppf(0.977 25, 3)` = 3.306 829 920 720 108; an element of `S` with
    /// a gravity component of infinite degrees of freedom has more.
    #[test]
    fn the_coverage_factor_follows_the_fits_degrees_of_freedom() {
        let f = fit(&noisy(12, 11, 1e-4, 13)).unwrap();
        let got = budget(&f, (3e-4, None), Coverage::default()).unwrap();
        for e in got.b {
            assert_eq!(e.effective_dof, Some(3));
            assert!((e.coverage_factor - 3.306_829_920_720_108).abs() < 1e-9);
            assert!((e.expanded - e.coverage_factor * e.combined).abs() <= 1e-15 * e.expanded);
        }
        let s00 = got.s[0][0];
        let by_hand = (s00.combined.powi(4) / (s00.statistical.powi(4) / 3.0)).floor() as u64;
        assert_eq!(s00.effective_dof, Some(by_hand));
        assert!(by_hand >= 3);
    }

    /// The gravity component against the fit itself: the same positions
    /// under a gravity 1 + ε (outputs `b + S (1 + ε) g`) give an `S` larger
    /// by `ε S` to first order and the same `b`.
    #[test]
    fn a_gravity_off_by_epsilon_scales_s_and_leaves_b() {
        let eps = 1e-4;
        let (b, t) = truth();
        let at = |scale: f64| {
            let means: Vec<[f64; 3]> = directions(12, 11)
                .into_iter()
                .map(|g| outputs(b, t, g.map(|x| x * scale)))
                .collect();
            fit(&means).unwrap()
        };
        let (nominal, off) = (at(1.0), at(1.0 + eps));
        let u = budget(&nominal, (eps, None), Coverage::Factor(1.0)).unwrap();
        for m in 0..3 {
            assert!((off.bias[m] - nominal.bias[m]).abs() < 1e-12, "b{m}");
            for k in 0..=m {
                let change = (off.s[m][k] - nominal.s[m][k]).abs();
                let first_order = eps * nominal.s[m][k].abs();
                assert!(
                    (change - first_order).abs() < 1e-7 * first_order.max(1e-9) + 1e-12,
                    "S{m}{k}: {change} vs {first_order}"
                );
                // The budget's component for the same ε.
                assert!(
                    (u.s[m][k].gravity - change).abs() < 1e-4 * change + 1e-12,
                    "S{m}{k}"
                );
            }
        }
    }

    #[test]
    fn without_standard_errors_there_is_no_budget() {
        let f = fit(&noisy(12, 11, 1e-4, 13)).unwrap();
        for (b, s) in [(false, true), (true, false)] {
            let mut g = f.clone();
            if !b {
                g.bias_std = None;
            }
            if !s {
                g.s_std = None;
            }
            assert_eq!(budget(&g, (1e-5, None), Coverage::default()), None);
        }
        assert!(budget(&f, (1e-5, None), Coverage::default()).is_some());
    }
}
