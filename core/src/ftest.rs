//! Upper-tail F tests, the statistic behind every warning that compares two
//! variances ([`crate::adequacy`], [`crate::quality`]).
//!
//! A statistic `F` with `ν1` and `ν2` degrees of freedom has the p-value
//! `p = P(F(ν1, ν2) > F)`, the upper tail of Snedecor's F distribution
//! (`statrs`, by the regularised incomplete beta function
//! `I_{ν2/(ν2 + ν1·F)}(ν2/2, ν1/2)`, accurate for tiny `p`). "F exceeds the
//! upper α point of F(ν1, ν2)" is the same statement as `p < α`, since the
//! tail is strictly decreasing in `F`.

use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

/// One F test: the statistic, its degrees of freedom, its p-value and the
/// level it is judged at.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FTest {
    /// The statistic.
    pub f: f64,
    /// Numerator degrees of freedom ν1.
    pub df1: usize,
    /// Denominator degrees of freedom ν2.
    pub df2: usize,
    /// `P(F(ν1, ν2) > f)`.
    pub p_value: f64,
    /// The level α: flagged when `p_value < alpha`.
    pub alpha: f64,
}

impl FTest {
    /// The test of `f` on `(df1, df2)` degrees of freedom at level `alpha`;
    /// `None` when a degree of freedom is zero or `f` is negative or not
    /// finite (a zero denominator variance), so no non-finite number leaves.
    pub fn new(f: f64, df1: usize, df2: usize, alpha: f64) -> Option<Self> {
        if df1 == 0 || df2 == 0 || !f.is_finite() || f < 0.0 {
            return None;
        }
        let dist = FisherSnedecor::new(df1 as f64, df2 as f64).ok()?;
        Some(FTest {
            f,
            df1,
            df2,
            p_value: dist.sf(f),
            alpha,
        })
    }

    /// The test of a ratio of two variances given as roots of sums of
    /// squares: `F = (num² / df1) / (den² / df2)`, formed from the ratio of
    /// the roots so that it neither under- nor overflows.
    pub fn of_roots(num: f64, df1: usize, den: f64, df2: usize, alpha: f64) -> Option<Self> {
        let ratio = num / den;
        FTest::new(ratio * ratio * (df2 as f64 / df1 as f64), df1, df2, alpha)
    }

    /// Whether `f` exceeds the upper `alpha` point (strictly).
    pub fn flagged(&self) -> bool {
        self.p_value < self.alpha
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Upper-tail points printed in F tables (and by scipy.stats.f.isf):
    /// at its own 5 % point the p-value is 5 %, at 1 % it is 1 %.
    #[test]
    fn p_values_match_printed_tables() {
        let t = |f, a, b| FTest::new(f, a, b, 0.05).unwrap().p_value;
        // F(1, 1) upper 5 %: 161.4476; F(3, 10) 5 %: 3.708265; F(6, 24) 1 %: 3.666717.
        assert!((t(161.447_638_797_588_2, 1, 1) - 0.05).abs() < 1e-9);
        assert!((t(3.708_264_819_046_843_5, 3, 10) - 0.05).abs() < 1e-9);
        assert!((t(3.666_716_717_945_315_3, 6, 24) - 0.01).abs() < 1e-9);
        // F(2, 2): p = 1/(1 + F) exactly.
        assert!((t(3.0, 2, 2) - 0.25).abs() < 1e-14);
        assert_eq!(t(0.0, 4, 7), 1.0);
    }

    #[test]
    fn flagged_strictly_below_alpha() {
        let at = |p_value| {
            FTest {
                f: 1.0,
                df1: 1,
                df2: 1,
                p_value,
                alpha: 0.01,
            }
            .flagged()
        };
        assert!(!at(0.01));
        assert!(at(0.009_999_999));
        assert!(!at(0.5));
        // F(2, 2) at 3: p = 1/(1 + 3) = 0.25.
        assert!(FTest::new(3.0, 2, 2, 0.250_001).unwrap().flagged());
        assert!(!FTest::new(3.0, 2, 2, 0.249_999).unwrap().flagged());
    }

    /// (3² / 2) / (2² / 8) = 9, and the roots' scale cancels.
    #[test]
    fn a_ratio_of_roots_is_a_ratio_of_variances() {
        let t = FTest::of_roots(3.0, 2, 2.0, 8, 0.01).unwrap();
        assert_eq!((t.f, t.df1, t.df2), (9.0, 2, 8));
        assert_eq!(FTest::of_roots(3e-200, 2, 2e-200, 8, 0.01).unwrap().f, 9.0);
        assert_eq!(FTest::of_roots(1.0, 1, 0.0, 3, 0.01), None);
    }

    #[test]
    fn no_test_without_degrees_of_freedom_or_a_finite_statistic() {
        assert_eq!(FTest::new(2.0, 0, 5, 0.01), None);
        assert_eq!(FTest::new(2.0, 5, 0, 0.01), None);
        assert_eq!(FTest::new(f64::INFINITY, 1, 5, 0.01), None);
        assert_eq!(FTest::new(f64::NAN, 1, 5, 0.01), None);
        assert_eq!(FTest::new(-1.0, 1, 5, 0.01), None);
        let t = FTest::new(2.0, 1, 5, 0.01).unwrap();
        assert_eq!((t.f, t.df1, t.df2, t.alpha), (2.0, 1, 5, 0.01));
    }
}
