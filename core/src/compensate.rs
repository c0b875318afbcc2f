//! Compensation: recover the input acceleration from a raw output.
//!
//! With `a_p` and `a_o` known (0 by default), the model is a cubic in `a_i`:
//!
//! ```text
//! U = c0 + c1·a_i + c2·a_i² + c3·a_i³
//! c0 = k0 + kp·a_p + ko·a_o + kop·a_o·a_p + kpp·a_p² + koo·a_o²
//! c1 = ki + kio·a_o + kpi·a_p
//! c2 = kii,   c3 = kiii
//! ```
//!
//! (absent terms count as 0). When `c2 = c3 = 0` the model is linear in `a_i`
//! and `a_i = (U − c0)/c1`. Otherwise Newton's iteration starts from that
//! linear solution, `a ← a − (f(a) − U)/f'(a)` with `f'(a) = c1 + 2·c2·a +
//! 3·c3·a²`, until the step is below `1e-14·max(1, |a|)`; it stops with an
//! error when `f'` vanishes or after [`MAX_ITERATIONS`] steps.

use crate::position::Gravity;
use crate::term::TermMap;
use crate::{CompensateError, Term};

/// Newton steps allowed before giving up.
pub const MAX_ITERATIONS: usize = 100;

/// A set of coefficients ready to evaluate and invert the model.
#[derive(Clone, Debug, PartialEq)]
pub struct Compensator {
    /// Coefficient of every term, 0 where absent, in [`Term::ALL`] order.
    k: [f64; 11],
}

impl Compensator {
    /// Prepares `coefficients` (which must include `ki`) for compensation.
    pub fn new(coefficients: &TermMap<f64>) -> Result<Self, CompensateError> {
        if coefficients.get(Term::Ki).is_none() {
            return Err(CompensateError::MissingScaleFactor);
        }
        if let Some((term, _)) = coefficients.iter().find(|(_, v)| !v.is_finite()) {
            return Err(CompensateError::NonFinite(term.name()));
        }
        let mut k = [0.0; 11];
        for (n, t) in Term::ALL.iter().enumerate() {
            k[n] = coefficients.get(*t).copied().unwrap_or(0.0);
        }
        Ok(Compensator { k })
    }

    fn get(&self, t: Term) -> f64 {
        self.k[t as usize]
    }

    /// The model's output at specific force `a` (eq. 2 plus `kiii·a_i³`).
    pub fn output(&self, a: &Gravity) -> f64 {
        Term::ALL
            .iter()
            .map(|t| self.get(*t) * t.regressor(a))
            .sum()
    }

    /// The input acceleration `a_i` (g) that produces output `u` with the
    /// given `a_p` and `a_o`.
    pub fn input(&self, u: f64, a_p: f64, a_o: f64) -> Result<f64, CompensateError> {
        for (name, v) in [("output", u), ("a_p", a_p), ("a_o", a_o)] {
            if !v.is_finite() {
                return Err(CompensateError::NonFinite(name));
            }
        }
        use Term::*;
        let c0 = self.get(K0)
            + self.get(Kp) * a_p
            + self.get(Ko) * a_o
            + self.get(Kop) * a_o * a_p
            + self.get(Kpp) * a_p * a_p
            + self.get(Koo) * a_o * a_o;
        let c1 = self.get(Ki) + self.get(Kio) * a_o + self.get(Kpi) * a_p;
        let (c2, c3) = (self.get(Kii), self.get(Kiii));
        if c1 == 0.0 {
            return Err(CompensateError::VanishingDerivative { a_i: 0.0 });
        }
        let mut a = (u - c0) / c1;
        if c2 == 0.0 && c3 == 0.0 {
            return finite(a, 0);
        }
        for step in 1..=MAX_ITERATIONS {
            let f = c0 + a * (c1 + a * (c2 + a * c3)) - u;
            let df = c1 + a * (2.0 * c2 + 3.0 * c3 * a);
            if df == 0.0 || !df.is_finite() {
                return Err(CompensateError::VanishingDerivative { a_i: a });
            }
            let delta = f / df;
            a -= delta;
            if !a.is_finite() {
                break;
            }
            if delta.abs() <= 1e-14 * a.abs().max(1.0) {
                return finite(a, step);
            }
        }
        Err(CompensateError::NoConvergence {
            iterations: MAX_ITERATIONS,
            a_i: a,
        })
    }
}

fn finite(a: f64, iterations: usize) -> Result<f64, CompensateError> {
    if a.is_finite() {
        Ok(a)
    } else {
        Err(CompensateError::NoConvergence { iterations, a_i: a })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn comp(pairs: &[(Term, f64)]) -> Compensator {
        Compensator::new(&TermMap(pairs.to_vec())).unwrap()
    }

    #[test]
    fn linear_model_inverts_in_closed_form() {
        let c = comp(&[(Term::K0, 0.1), (Term::Ki, 2.0), (Term::Kp, 0.5)]);
        // U = 0.1 + 2·a_i + 0.5·a_p; a_p = 1, U = 1.6 → a_i = 0.5.
        assert_eq!(c.input(1.6, 1.0, 0.0), Ok(0.5));
    }

    #[test]
    fn cubic_model_inverts_by_newton() {
        let c = comp(&[
            (Term::K0, 1e-3),
            (Term::Ki, 1.2),
            (Term::Kii, 0.02),
            (Term::Kiii, -0.01),
        ]);
        for a in [-1.5, -0.3, 0.0, 0.7, 1.9] {
            let u = c.output(&Gravity {
                i: a,
                p: 0.0,
                o: 0.0,
            });
            assert!((c.input(u, 0.0, 0.0).unwrap() - a).abs() < 1e-14);
        }
    }

    /// `U = a + a²/2` has the roots 1 and −3 of `U = 1.5`; from the linear
    /// start 1.5, Newton with the right derivative `1 + a` lands on 1.
    #[test]
    fn quadratic_model_inverts_to_the_root_near_the_linear_start() {
        let c = comp(&[(Term::Ki, 1.0), (Term::Kii, 0.5)]);
        assert_eq!(c.input(1.5, 0.0, 0.0), Ok(1.0));
        // U = 2a − 0.1·a² at a = 0.5: U = 0.975 exactly representable? no,
        // but the root is: a = 10 − sqrt(100 − 10·U) = 0.5.
        let c = comp(&[(Term::Ki, 2.0), (Term::Kii, -0.1)]);
        let a = c.input(0.975, 0.0, 0.0).unwrap();
        assert!((a - 0.5).abs() < 1e-15, "{a}");
    }

    /// The cross terms enter through `c0` and `c1` (module docs): with
    /// a_p = 0.5, a_o = −0.25 the model is linear in a_i with
    /// c0 = k0 + kp·a_p + ko·a_o + kop·a_o·a_p + kpp·a_p² + koo·a_o²
    ///    = 0.1 + 0.1 − 0.1 − 0.1 + 0.4 + 0.2 = 0.6,
    /// c1 = ki + kio·a_o + kpi·a_p = 2 + 0.4·(−0.25) + 0.6·0.5 = 2.2.
    #[test]
    fn cross_terms_enter_the_inversion_as_derived() {
        let c = comp(&[
            (Term::K0, 0.1),
            (Term::Ki, 2.0),
            (Term::Kp, 0.2),
            (Term::Ko, 0.4),
            (Term::Kio, 0.4),
            (Term::Kop, 0.8),
            (Term::Kpi, 0.6),
            (Term::Kpp, 1.6),
            (Term::Koo, 3.2),
        ]);
        // U = c0 + c1·a_i at a_i = 0.25: 0.6 + 0.55 = 1.15.
        let a = c.input(1.15, 0.5, -0.25).unwrap();
        assert!((a - 0.25).abs() < 1e-15, "{a}");
        // With a second-order term too, Newton must use the same c1:
        // U = 0.6 + 2.2·a + 0.5·a², a = 0.25 → U = 1.18125.
        let mut k = c.k;
        k[Term::Kii as usize] = 0.5;
        let c = Compensator { k };
        let a = c.input(1.18125, 0.5, -0.25).unwrap();
        assert!((a - 0.25).abs() < 1e-15, "{a}");
    }

    /// For |a_i| ≫ 1 the stopping rule is relative (1e-14·|a|): rounding at
    /// that magnitude never makes the step smaller than an absolute 1e-14.
    #[test]
    fn large_inputs_converge_by_the_relative_step() {
        let c = comp(&[(Term::Ki, 1.0), (Term::Kii, 1e-9)]);
        // U = a + 1e-9·a² at a = 1e6: U = 1e6 + 1e3.
        let a = c.input(1_001_000.0, 0.0, 0.0).unwrap();
        assert!((a - 1e6).abs() < 1e-6, "{a}");
    }

    /// A third-order model without a second-order term is not linear.
    #[test]
    fn cubic_without_quadratic_term_is_solved_by_newton() {
        // U = a + a³ at a = 0.5: U = 0.625.
        let c = comp(&[(Term::Ki, 1.0), (Term::Kiii, 1.0)]);
        let a = c.input(0.625, 0.0, 0.0).unwrap();
        assert!((a - 0.5).abs() < 1e-15, "{a}");
    }

    /// Newton needs the true derivative 1 + 2a + 3a²: `U = a + a² + a³ = 3`
    /// has the single real root 1, and the linear start 3 lies where a wrong
    /// sign in the derivative sends the iteration away from it.
    #[test]
    fn the_derivative_has_every_term() {
        let c = comp(&[(Term::Ki, 1.0), (Term::Kii, 1.0), (Term::Kiii, 1.0)]);
        let a = c.input(3.0, 0.0, 0.0).unwrap();
        assert!((a - 1.0).abs() < 1e-15, "{a}");
    }

    /// A root in the thousands, where rounding keeps the last steps near
    /// 1e-12: the relative stopping rule (1e-14·|a|) ends the iteration; an
    /// absolute one would not. Reference root by bisection in 40 digits:
    /// 7640.1079254448585051848…
    #[test]
    fn a_large_root_converges_by_the_relative_step() {
        let c = comp(&[(Term::Ki, 1.0), (Term::Kii, 1e-3), (Term::Kiii, 1e-6)]);
        let a = c.input(511_974.0, 0.0, 0.0).unwrap();
        assert!((a - 7_640.107_925_444_858).abs() < 1e-11, "{a}");
    }

    /// A derivative that vanishes exactly at an iterate is reported as such.
    #[test]
    fn a_vanishing_derivative_during_newton_is_named() {
        // U = a + a²: the linear start for U = −0.5 is a = −0.5, where
        // dU/da = 1 + 2a = 0.
        let c = comp(&[(Term::Ki, 1.0), (Term::Kii, 1.0)]);
        assert_eq!(
            c.input(-0.5, 0.0, 0.0),
            Err(CompensateError::VanishingDerivative { a_i: -0.5 })
        );
    }

    #[test]
    fn refusals_are_typed() {
        assert_eq!(
            Compensator::new(&TermMap(vec![(Term::K0, 1.0)])),
            Err(CompensateError::MissingScaleFactor)
        );
        let c = comp(&[(Term::Ki, 1.0), (Term::Kpi, -1.0)]);
        // c1 = ki + kpi·a_p = 0 at a_p = 1.
        assert_eq!(
            c.input(0.3, 1.0, 0.0),
            Err(CompensateError::VanishingDerivative { a_i: 0.0 })
        );
        assert_eq!(
            c.input(f64::NAN, 0.0, 0.0),
            Err(CompensateError::NonFinite("output"))
        );
        // U = a + a² never goes below −1/4: U = −1 has no real solution.
        let bowl = comp(&[(Term::Ki, 1.0), (Term::Kii, 1.0)]);
        assert!(matches!(
            bowl.input(-1.0, 0.0, 0.0),
            Err(CompensateError::NoConvergence { .. } | CompensateError::VanishingDerivative { .. })
        ));
    }
}
