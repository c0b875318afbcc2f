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
//! * **combined** and **expanded** as in the single-axis budget.
//!
//! `S`'s elements above the diagonal are zero by the frame convention (the
//! sensor's x axis and xy-plane define the frame): not measured, their
//! budget is zero. With exactly nine positions the fit has no degree of
//! freedom and no standard error, and there is no budget.

use serde::Serialize;

use crate::gravity_fit::GravityFit;
use crate::uncertainty::TermBudget;

/// The budget of a triad found from the gravity magnitude.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GravityBudget {
    /// The coverage factor `k` of the expanded uncertainties.
    pub coverage_factor: f64,
    /// The fit's residual degrees of freedom (`n − 9`), which the
    /// statistical components rest on.
    pub degrees_of_freedom: usize,
    /// Per element of `b`.
    pub b: [TermBudget; 3],
    /// Per element of `S`, rows by axis.
    pub s: [[TermBudget; 3]; 3],
}

/// The budget of `fit` for a gravity magnitude of relative uncertainty
/// `gravity_rel_std` (1σ) and a coverage factor; `None` without standard
/// errors (exactly nine positions).
pub fn budget(
    fit: &GravityFit,
    gravity_rel_std: f64,
    coverage_factor: f64,
) -> Option<GravityBudget> {
    let (b_std, s_std) = (fit.bias_std?, fit.s_std?);
    let element = |statistical: f64, gravity: f64| {
        TermBudget::new(statistical, 0.0, gravity, 0.0, coverage_factor)
    };
    Some(GravityBudget {
        coverage_factor,
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
        let got = budget(&f, u, 2.0).unwrap();
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
        let u = budget(&nominal, eps, 1.0).unwrap();
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
            assert_eq!(budget(&g, 1e-5, 2.0), None);
        }
        assert!(budget(&f, 1e-5, 2.0).is_some());
    }
}
