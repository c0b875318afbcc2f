//! What a run gives at one position: its samples, or their summary as a
//! station that averages on board computes it.
//!
//! Of a position's samples `u_1 … u_n` the method needs three things: the
//! count `n`, the mean `ū = Σ u_s / n` (the position's value, which each run
//! is identified on), and the root of the squared deviations
//! `√Σ (u_s − ū)²` (the pure error, [`crate::adequacy`]). A summary gives
//! `ū`, the sample standard deviation `s = √(Σ (u_s − ū)² / (n − 1))` and
//! `n`; the root is then `s·√(n − 1)`. Samples and their summary therefore
//! calibrate alike, to rounding.

use crate::fusion::{mean, scaled_norm};

/// A position's reading in one run.
#[derive(Clone, Debug, PartialEq)]
pub enum Reading {
    /// The samples themselves.
    Samples(Vec<f64>),
    /// Their summary.
    Summary(Summary),
}

/// The summary of `count` samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    /// `ū`, their mean.
    pub mean: f64,
    /// `s`, their sample standard deviation (divisor `n − 1`); 0 for one sample.
    pub std: f64,
    /// `n`, how many samples were averaged.
    pub count: u64,
}

/// Why a reading cannot be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Fault {
    /// No samples (or a count of 0).
    #[error("no samples")]
    Empty,
    /// The sample at this index is NaN or infinite.
    #[error("sample {0} is not a finite number")]
    NonFinite(usize),
    /// The summary's mean or standard deviation is not finite.
    #[error("the mean or standard deviation is not a finite number")]
    SummaryNotFinite,
    /// The summary's standard deviation is negative.
    #[error("the standard deviation is negative")]
    NegativeStd,
    /// One sample cannot scatter: its standard deviation must be 0.
    #[error("one sample has no spread: its standard deviation must be 0")]
    SpreadOfOne,
}

impl From<Vec<f64>> for Reading {
    fn from(samples: Vec<f64>) -> Self {
        Reading::Samples(samples)
    }
}

impl Reading {
    /// Whether the reading can be used: samples, all finite; or a summary
    /// of at least one sample with a finite mean and a finite, non-negative
    /// standard deviation (0 for one sample).
    pub fn check(&self) -> Result<(), Fault> {
        match self {
            Reading::Samples(s) if s.is_empty() => Err(Fault::Empty),
            Reading::Samples(s) => match s.iter().position(|u| !u.is_finite()) {
                Some(k) => Err(Fault::NonFinite(k)),
                None => Ok(()),
            },
            Reading::Summary(s) if s.count == 0 => Err(Fault::Empty),
            Reading::Summary(s) if !s.mean.is_finite() || !s.std.is_finite() => {
                Err(Fault::SummaryNotFinite)
            }
            Reading::Summary(s) if s.std < 0.0 => Err(Fault::NegativeStd),
            Reading::Summary(s) if s.count == 1 && s.std != 0.0 => Err(Fault::SpreadOfOne),
            Reading::Summary(_) => Ok(()),
        }
    }

    /// `n`, the number of samples.
    pub fn count(&self) -> u64 {
        match self {
            Reading::Samples(s) => s.len() as u64,
            Reading::Summary(s) => s.count,
        }
    }

    /// `ū`, the position's value.
    pub fn mean(&self) -> f64 {
        match self {
            Reading::Samples(s) => mean(s),
            Reading::Summary(s) => s.mean,
        }
    }

    /// `√Σ (u_s − ū)²`, or `s·√(n − 1)` from a summary.
    pub fn deviation_norm(&self) -> f64 {
        match self {
            Reading::Samples(s) => {
                let m = mean(s);
                scaled_norm(s.iter().map(move |x| x - m))
            }
            Reading::Summary(s) => s.std * (s.count.saturating_sub(1) as f64).sqrt(),
        }
    }

    /// `n − 1`, the degrees of freedom of the scatter.
    pub fn dof(&self) -> u64 {
        self.count().saturating_sub(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1, 2, 4, 9 by hand: ū = 4, deviations −3, −2, 0, 5, Σ² = 38,
    /// s = √(38/3).
    #[test]
    fn samples_and_their_summary_agree() {
        let samples = Reading::from(vec![1.0, 2.0, 4.0, 9.0]);
        let summary = Reading::Summary(Summary {
            mean: 4.0,
            std: (38.0f64 / 3.0).sqrt(),
            count: 4,
        });
        for r in [&samples, &summary] {
            assert_eq!(r.check(), Ok(()));
            assert_eq!(r.count(), 4);
            assert_eq!(r.dof(), 3);
            assert_eq!(r.mean(), 4.0);
            assert!((r.deviation_norm() - 38f64.sqrt()).abs() < 1e-14);
        }
    }

    #[test]
    fn unusable_readings_say_why() {
        let summary = |mean, std, count| Reading::Summary(Summary { mean, std, count });
        assert_eq!(Reading::from(vec![]).check(), Err(Fault::Empty));
        assert_eq!(
            Reading::from(vec![1.0, f64::NAN]).check(),
            Err(Fault::NonFinite(1))
        );
        assert_eq!(summary(1.0, 0.0, 0).check(), Err(Fault::Empty));
        assert_eq!(
            summary(f64::INFINITY, 0.0, 2).check(),
            Err(Fault::SummaryNotFinite)
        );
        assert_eq!(
            summary(1.0, f64::NAN, 2).check(),
            Err(Fault::SummaryNotFinite)
        );
        assert_eq!(summary(1.0, -1e-9, 2).check(), Err(Fault::NegativeStd));
        assert_eq!(summary(1.0, 0.1, 1).check(), Err(Fault::SpreadOfOne));
        assert_eq!(summary(1.0, 0.0, 1).check(), Ok(()));
        assert_eq!(summary(1.0, 0.0, 1).deviation_norm(), 0.0);
    }
}
