//! Degrees of freedom and the coverage factor (GUM G.4, G.6; ILAC P14).
//!
//! An expanded uncertainty `U = k·u_c` covers the measurand with the
//! probability `p` only when `k` is chosen from the distribution of
//! `(y − Y)/u_c`, which for a combined standard uncertainty built from
//! components with finite degrees of freedom is Student's t with the
//! **effective degrees of freedom** of Welch–Satterthwaite (GUM G.2b):
//!
//! ```text
//! ν_eff = u_c⁴ / Σ_i (u_i⁴ / ν_i),   truncated to an integer (GUM G.6.4)
//! ```
//!
//! where a component with `ν_i = ∞` (a Type B component whose source states
//! no degrees of freedom) adds nothing to the sum, and components with
//! `u_i = 0` add nothing either. When nothing is left in the sum `ν_eff`
//! is infinite (`None` here) and `t` becomes the normal distribution.
//!
//! **The coverage factor** for a stated probability `p` is the two-sided
//! Student t quantile
//!
//! ```text
//! k = t_{(1+p)/2}(ν_eff)
//! ```
//!
//! so `k = 2` at `p = 0.9545` only as `ν_eff → ∞` (for `ν_eff = 3`,
//! `k = 3.31`; for `ν_eff = 4`, `k = 2.87`). A sensor type that fixes `k` instead states the probability
//! it achieves, `p = 2·F_t(k; ν_eff) − 1`.
//!
//! **The statistical component of a fused coefficient** is the standard
//! error of the weighted mean of the batch means `x⁺ = Σ_b w_b x̄_b / W`,
//! `w_b = n_b / s_b²` (the weights actually used: a floored batch's `s_b` is
//! its floor, [`crate::fusion`]), `W = Σ_b w_b`, so `Var(x⁺) = Σ_b (w_b/W)²
//! s_b²/n_b` with each `s_b²` on `n_b − 1` degrees of freedom, and
//! Welch–Satterthwaite gives
//!
//! ```text
//! ν_stat = (Σ_b (w_b/W)² s_b²/n_b)² / Σ_b ((w_b/W)² s_b²/n_b)² / (n_b − 1)
//!        = 1 / Σ_b (w_b/W)² / (n_b − 1)
//! ```
//!
//! (the second line since `(w_b/W)² s_b²/n_b = w_b/W²`). One batch gives
//! `n − 1`; a single run, its own residual degrees of freedom `m − p`.

use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// The coverage probability of a sensor without a type, or of a type that
/// states none: about two standard deviations of a normal distribution.
pub const DEFAULT_PROBABILITY: f64 = 0.9545;

/// What an expanded uncertainty holds fixed: the probability it must cover
/// (the coverage factor then follows from the degrees of freedom), or the
/// coverage factor (the probability then follows).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Coverage {
    /// A coverage probability, `0 < p < 1`.
    Probability(f64),
    /// A coverage factor, `k > 0`.
    Factor(f64),
}

impl Default for Coverage {
    fn default() -> Self {
        Coverage::Probability(DEFAULT_PROBABILITY)
    }
}

/// The coverage factor and probability of one expanded uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covered {
    /// `ν_eff`, truncated; `None` when infinite.
    pub effective_dof: Option<u64>,
    /// `k`.
    pub factor: f64,
    /// `p`.
    pub probability: f64,
}

impl Coverage {
    /// `k` and `p` for a combined uncertainty of `effective_dof` degrees of
    /// freedom (`None`: infinite).
    ///
    /// Remembered per thread (`Remembered`): Student's quantile costs
    /// 2–6 µs an evaluation (statrs inverts the regularised incomplete beta
    /// function iteratively), a stated factor's probability sixty-four of
    /// them, and every term of every budget asks — while a lab's budgets
    /// ask the same few questions again and again.
    pub fn at(self, effective_dof: Option<u64>) -> Covered {
        REMEMBERED.with_borrow_mut(|r| r.at(self, effective_dof))
    }

    /// [`Coverage::at`], computed.
    fn computed(self, effective_dof: Option<u64>) -> Covered {
        let (factor, probability) = match self {
            Coverage::Probability(p) => (factor(p, effective_dof), p),
            Coverage::Factor(k) => (k, probability(k, effective_dof)),
        };
        Covered {
            effective_dof,
            factor,
            probability,
        }
    }

    /// The question as a key: which is fixed, its bits, the degrees of
    /// freedom.
    fn key(self, effective_dof: Option<u64>) -> (bool, u64, Option<u64>) {
        match self {
            Coverage::Probability(p) => (false, p.to_bits(), effective_dof),
            Coverage::Factor(k) => (true, k.to_bits(), effective_dof),
        }
    }
}

/// Answers of [`Coverage::at`] kept for the next time the same question
/// is asked: the same bits as computing them again, since the question's
/// bits are the key. At most [`Remembered::KEPT`] answers; forgotten all at
/// once when full (a lab asks far fewer distinct questions).
#[derive(Default)]
struct Remembered(std::collections::HashMap<(bool, u64, Option<u64>), Covered>);

impl Remembered {
    const KEPT: usize = 4096;

    fn at(&mut self, coverage: Coverage, effective_dof: Option<u64>) -> Covered {
        let key = coverage.key(effective_dof);
        if let Some(c) = self.0.get(&key) {
            return *c;
        }
        if self.0.len() >= Self::KEPT {
            self.0.clear();
        }
        let c = coverage.computed(effective_dof);
        self.0.insert(key, c);
        c
    }
}

thread_local! {
    static REMEMBERED: std::cell::RefCell<Remembered> = std::cell::RefCell::default();
}

/// `ν_eff = u_c⁴ / Σ_i u_i⁴/ν_i` over `(u_i, ν_i)` (`ν_i` `None`: infinite),
/// truncated to an integer; `None` when infinite (no component with a
/// finite `ν_i` and `u_i > 0`, or more than `u64` counts). Computed on
/// `u_i/u_max` so that neither the fourth powers of tiny uncertainties
/// underflow nor those of huge ones overflow; a `ν_eff` below 1 (not
/// reachable with every `ν_i ≥ 1`) is 1.
pub fn effective_dof(components: &[(f64, Option<f64>)]) -> Option<u64> {
    let scale = components.iter().fold(0.0_f64, |m, (u, _)| m.max(u.abs()));
    let r = |u: f64| (u / scale).powi(2);
    let combined: f64 = components.iter().map(|(u, _)| r(*u)).sum();
    let sum: f64 = components
        .iter()
        .filter_map(|(u, nu)| nu.map(|nu| r(*u).powi(2) / nu))
        .sum();
    // All zero (0/0), all Type B (a zero sum) or past any count of degrees
    // of freedom: infinite.
    let nu = combined.powi(2) / sum;
    (nu.is_finite() && nu < u64::MAX as f64).then(|| (nu.floor() as u64).max(1))
}

/// `ν_stat` of a fused value from its batches' sizes `n_b` and the weights
/// `w_b` they were fused with (any common scale): `1 / Σ_b (w_b/W)²/(n_b − 1)`.
/// A batch of fewer than two values carries no degree of freedom and makes
/// the result 0.
pub fn fused_dof(batches: &[(usize, f64)]) -> f64 {
    let total: f64 = batches.iter().map(|(_, w)| w).sum();
    let mut sum = 0.0;
    for (n, w) in batches {
        if *n < 2 {
            return 0.0;
        }
        sum += (w / total).powi(2) / (*n - 1) as f64;
    }
    if sum > 0.0 { 1.0 / sum } else { 0.0 }
}

/// Above this many degrees of freedom Student's t quantile is Fisher's
/// expansion about the normal one: statrs' inverse loses digits there
/// (8e-10 at 1e5) and gives nonsense or never returns beyond 1e7, while the
/// expansion's next term is below 1e-16 relative from 1000 on.
const LARGE_DOF: u64 = 1000;

/// `k = t_{(1+p)/2}(ν)`, the normal quantile when `ν` is infinite (`None`).
/// For `ν` past `LARGE_DOF`, Fisher's expansion (Abramowitz & Stegun
/// 26.7.5) about the normal quantile `z`:
///
/// ```text
/// t = z + g₁/ν + g₂/ν² + g₃/ν³ + g₄/ν⁴,   g₁ = (z³ + z)/4,
/// g₂ = (5z⁵ + 16z³ + 3z)/96,   g₃ = (3z⁷ + 19z⁵ + 17z³ − 15z)/384,
/// g₄ = (79z⁹ + 776z⁷ + 1482z⁵ − 1920z³ − 945z)/92160
/// ```
pub fn factor(p: f64, dof: Option<u64>) -> f64 {
    let q = (1.0 + p) / 2.0;
    let z = Normal::standard().inverse_cdf(q);
    match dof {
        Some(nu) if nu <= LARGE_DOF => StudentsT::new(0.0, 1.0, nu as f64)
            .map(|t| t.inverse_cdf(q))
            .unwrap_or(f64::NAN),
        Some(nu) => {
            let n = nu as f64;
            let g1 = (z.powi(3) + z) / 4.0;
            let g2 = (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / 96.0;
            let g3 = (3.0 * z.powi(7) + 19.0 * z.powi(5) + 17.0 * z.powi(3) - 15.0 * z) / 384.0;
            let g4 = (79.0 * z.powi(9) + 776.0 * z.powi(7) + 1482.0 * z.powi(5)
                - 1920.0 * z.powi(3)
                - 945.0 * z)
                / 92160.0;
            z + g1 / n + g2 / n.powi(2) + g3 / n.powi(3) + g4 / n.powi(4)
        }
        None => z,
    }
}

/// `p = 2·F_t(k; ν) − 1`, the normal's when `ν` is infinite (`None`): for
/// a finite `ν`, the `p` whose [`factor`] is `k`, found by bisection
/// (sixty-four evaluations of [`factor`], so exactly as accurate — statrs'
/// own t distribution loses digits past 1e5 degrees of freedom and is wrong
/// past 1e9).
pub fn probability(k: f64, dof: Option<u64>) -> f64 {
    if dof.is_none() {
        return 2.0 * Normal::standard().cdf(k) - 1.0;
    }
    // Sixty-four halvings of [0, 1] leave less than a unit in the last
    // place of any p ≥ 2⁻¹¹: converged.
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..64 {
        let mid = (lo + hi) / 2.0;
        match factor(mid, dof).total_cmp(&k) {
            std::cmp::Ordering::Less => lo = mid,
            std::cmp::Ordering::Greater => hi = mid,
            std::cmp::Ordering::Equal => return mid,
        }
    }
    (lo + hi) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values from scipy 1.17: `stats.t.ppf((1 + p)/2, ν)`,
    /// `2·stats.t.cdf(k, ν) − 1`, `stats.norm.ppf(0.97725)`.
    #[test]
    fn factors_and_probabilities_are_students() {
        let cases = [
            (0.9545, Some(1), 13.967_811_487_502_55),
            (0.9545, Some(3), 3.306_829_920_720_108),
            (0.9545, Some(4), 2.869_315_169_696_382_6),
            (0.9545, Some(10), 2.283_681_613_299_64),
            (0.95, Some(8), 2.306_004_135_204_166),
            (0.9545, Some(1000), 2.002_505_517_218_672),
            (0.9545, Some(100_000), 2.000_027_444_285_284_3),
            (0.9545, Some(1_000_000_000), 2.000_002_446_399_610_4),
            (0.9545, None, 2.000_002_443_899_602_7),
        ];
        for (p, nu, k) in cases {
            let got = factor(p, nu);
            assert!((got - k).abs() < 1e-9 * k, "{p} {nu:?}: {got} ≠ {k}");
            let back = probability(k, nu);
            assert!((back - p).abs() < 1e-10, "{p} {nu:?}: {back}");
        }
        // Just past the switch to Fisher's expansion, where its third and
        // fourth terms still count: scipy to 4e-15.
        for (p, nu, k) in [
            (0.9545, 1001, 2.002_503_013_583_816_7),
            (0.9545, 1500, 2.001_670_477_826_827_3),
            (0.99, 1001, 2.580_749_768_750_524_5),
            (0.99, 2000, 2.578_289_787_557_518_6),
        ] {
            let got = factor(p, Some(nu));
            assert!((got - k).abs() <= 4e-15 * k, "{p} {nu}: {got} ≠ {k}");
        }
        // The probability k = 2 reaches, scipy's 2·t.cdf(2, ν) − 1, also
        // where statrs' own distribution is off (1e7, 1e9).
        for (nu, p) in [
            (1_000, 0.954_229_653_506_748_3),
            (100_000, 0.954_497_036_542_493_4),
            (10_000_000, 0.954_499_709_108_157_1),
            (1_000_000_000, 0.954_499_735_833_686_9),
        ] {
            let got = probability(2.0, Some(nu));
            assert!((got - p).abs() < 1e-13, "{nu}: {got} ≠ {p}");
        }
        // k = 2 on 4 degrees of freedom covers 88.4 %, not 95.45 %.
        assert!((probability(2.0, Some(4)) - 0.883_883_476_483_184_4).abs() < 1e-12);
    }

    #[test]
    fn welch_satterthwaite_by_hand() {
        // u = (3, 4) on (4, ∞): u_c² = 25, ν = 625 / (81/4) = 30.86 → 30.
        assert_eq!(effective_dof(&[(3.0, Some(4.0)), (4.0, None)]), Some(30));
        // u = (1, 1) on (2, 2): ν = 4 / (1/2 + 1/2) = 4.
        assert_eq!(
            effective_dof(&[(1.0, Some(2.0)), (1.0, Some(2.0))]),
            Some(4)
        );
        // Only Type B, or only zeros: infinite.
        assert_eq!(effective_dof(&[(3.0, None), (0.0, Some(2.0))]), None);
        assert_eq!(effective_dof(&[(0.0, Some(2.0))]), None);
        assert_eq!(effective_dof(&[]), None);
        // A statistical component swamped by a Type B one: 1e20 degrees of
        // freedom are more than a count holds, so infinite; 1e18 are not.
        assert_eq!(effective_dof(&[(1e-5, Some(1.0)), (1.0, None)]), None);
        let huge = effective_dof(&[(1e-5, Some(0.01)), (1.0, None)]).unwrap();
        assert!((huge as f64 / 1e18 - 1.0).abs() < 1e-9, "{huge}");
        // 2⁶⁴ (exact in binary) is past what a count holds: infinite.
        assert_eq!(effective_dof(&[(1.0, Some(2f64.powi(64)))]), None);
        assert_eq!(effective_dof(&[(1.0, Some(2f64.powi(63)))]), Some(1 << 63));
        // Below one (not reachable with ν_i ≥ 1): one.
        assert_eq!(effective_dof(&[(1.0, Some(0.25))]), Some(1));
        // Scale-free: 1e-200 and 1e200 give what 1 does.
        for s in [1e-200, 1e200] {
            assert_eq!(
                effective_dof(&[(3.0 * s, Some(4.0)), (4.0 * s, None)]),
                Some(30)
            );
        }
    }

    #[test]
    fn a_fused_values_degrees_of_freedom() {
        // Equal weights, two batches of three: 1 / (2 · (1/4)/2) = 4.
        assert!((fused_dof(&[(3, 1.0), (3, 1.0)]) - 4.0).abs() < 1e-12);
        // One batch of n: n − 1.
        assert!((fused_dof(&[(6, 0.3)]) - 5.0).abs() < 1e-12);
        // Weights 1 and 3 on batches of 2 and 3: 1 / ((1/4)²/1 + (3/4)²/2).
        let want = 1.0 / (1.0 / 16.0 + 9.0 / 32.0);
        assert!((fused_dof(&[(2, 1.0), (3, 3.0)]) - want).abs() < 1e-12);
        assert_eq!(fused_dof(&[(1, 1.0), (3, 1.0)]), 0.0);
        assert_eq!(fused_dof(&[]), 0.0);
    }

    /// An answer remembered is bit for bit the one computed, for either
    /// coverage and every kind of degrees of freedom, asked twice; a full
    /// memory starts again rather than growing.
    #[test]
    fn a_remembered_answer_is_the_computed_one() {
        let mut r = Remembered::default();
        let bits = |c: Covered| (c.factor.to_bits(), c.probability.to_bits(), c.effective_dof);
        for coverage in [
            Coverage::default(),
            Coverage::Probability(0.95),
            Coverage::Factor(2.0),
            Coverage::Factor(3.0),
        ] {
            for nu in [
                Some(1),
                Some(4),
                Some(1000),
                Some(1001),
                Some(1 << 40),
                None,
            ] {
                let computed = bits(coverage.computed(nu));
                assert_eq!(bits(r.at(coverage, nu)), computed, "{coverage:?} {nu:?}");
                assert_eq!(
                    bits(r.at(coverage, nu)),
                    computed,
                    "{coverage:?} {nu:?} again"
                );
                assert_eq!(
                    bits(coverage.at(nu)),
                    computed,
                    "{coverage:?} {nu:?} per thread"
                );
            }
        }
        assert_eq!(r.0.len(), 24);
        for nu in 1..=Remembered::KEPT as u64 {
            r.at(Coverage::default(), Some(2000 + nu));
        }
        assert!(r.0.len() < Remembered::KEPT, "{}", r.0.len());
    }

    #[test]
    fn a_fixed_factor_states_its_probability() {
        let c = Coverage::Factor(2.0).at(Some(4));
        assert_eq!(c.factor, 2.0);
        assert!((c.probability - 0.883_883_476_483_184_4).abs() < 1e-12);
        let c = Coverage::default().at(Some(4));
        assert_eq!(c.probability, DEFAULT_PROBABILITY);
        assert!((c.factor - 2.869_315_169_696_382_6).abs() < 1e-9);
    }
}
