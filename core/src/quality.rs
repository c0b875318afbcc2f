//! Quality flags: warnings about a calibration that is computed but weak.
//! They never change a number.
//!
//! * **ill_conditioned**: the design's condition number exceeds
//!   [`ILL_CONDITIONED`]; the terms named are those whose component in the
//!   unit right singular vector of the smallest singular value has magnitude
//!   at least 0.1 — the combination the positions barely separate (in 1 g,
//!   `a_i² + a_p² + a_o² = 1` makes `k0` with `kii`, `kpp`, `koo` such a
//!   combination, nearly singular once explicit components are rounded).
//! * **noisy_run**: a run whose residual RMS exceeds 3 × the median residual
//!   RMS of the runs (with at least three runs, so the median is not the
//!   run itself or halfway to it): a stand that moved or a glitching sensor.
//!   Without spare positions every run fits exactly, every RMS is 0 and
//!   nothing is flagged.

use serde::Serialize;

use crate::fusion::mean;
use crate::identify::Design;
use crate::term::Term;
use crate::tumble::Calibration;

/// Condition number above which the design is flagged.
pub const ILL_CONDITIONED: f64 = 1e6;

/// Smallest component of the weakest direction that names a term.
pub const PARTICIPATION: f64 = 0.1;

/// A run's residual RMS beyond this multiple of the median is flagged.
pub const NOISY_FACTOR: f64 = 3.0;

/// One warning.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Warning {
    /// The design barely separates these terms.
    IllConditioned {
        /// The design's condition number.
        condition_number: f64,
        /// The terms in the weakest direction.
        terms: Vec<Term>,
    },
    /// A run fits much worse than the others.
    NoisyRun {
        /// Run index (0-based).
        run: usize,
        /// Its residual RMS.
        residual_rms: f64,
        /// The median residual RMS of the runs.
        median_residual_rms: f64,
    },
}

/// The quality of a calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Quality {
    /// The design's condition number.
    pub condition_number: f64,
    /// Every warning, possibly none.
    pub warnings: Vec<Warning>,
}

/// The median of some values (the mean of the middle two for an even count).
fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        mean(&v[n / 2 - 1..=n / 2])
    }
}

/// Whether a condition number is flagged (strictly above [`ILL_CONDITIONED`]).
fn ill_conditioned(condition_number: f64) -> bool {
    condition_number > ILL_CONDITIONED
}

/// The runs whose residual RMS exceeds [`NOISY_FACTOR`] × the median of
/// all runs' (none with fewer than three runs).
fn noisy(rms: &[f64]) -> Vec<Warning> {
    if rms.len() < 3 {
        return Vec::new();
    }
    let median_residual_rms = median(rms);
    rms.iter()
        .enumerate()
        .filter(|(_, r)| **r > NOISY_FACTOR * median_residual_rms)
        .map(|(run, r)| Warning::NoisyRun {
            run,
            residual_rms: *r,
            median_residual_rms,
        })
        .collect()
}

/// The flags of a calibration on its design.
pub fn assess(design: &Design, calibration: &Calibration) -> Quality {
    let condition_number = design.condition_number();
    let mut warnings = Vec::new();
    if ill_conditioned(condition_number) {
        let terms = design
            .weakest_direction()
            .iter()
            .filter(|(_, v)| v.abs() >= PARTICIPATION)
            .map(|(t, _)| t)
            .collect();
        warnings.push(Warning::IllConditioned {
            condition_number,
            terms,
        });
    }
    let rms: Vec<f64> = calibration.runs.iter().map(|r| r.residual_rms).collect();
    warnings.extend(noisy(&rms));
    Quality {
        condition_number,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&[5.0, 1.0, 3.0]), 3.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 10.0]), 3.5);
        assert_eq!(median(&[2.0, 8.0]), 5.0);
        assert_eq!(median(&[7.0]), 7.0);
    }

    #[test]
    fn the_threshold_is_strict() {
        assert!(!ill_conditioned(ILL_CONDITIONED));
        assert!(ill_conditioned(1.000_000_1e6));
        assert!(!ill_conditioned(10.0));
    }

    fn flagged(rms: &[f64]) -> Vec<usize> {
        noisy(rms)
            .into_iter()
            .map(|w| match w {
                Warning::NoisyRun { run, .. } => run,
                other => panic!("{other:?}"),
            })
            .collect()
    }

    #[test]
    fn a_run_is_noisy_strictly_beyond_three_medians() {
        // Median 1: 3 is not beyond 3 × 1, a hair more is.
        assert_eq!(flagged(&[1.0, 1.0, 3.0]), Vec::<usize>::new());
        assert_eq!(flagged(&[1.0, 1.0, 3.000_000_1]), vec![2]);
        // Median 1 of five; only the 9 stands out.
        assert_eq!(flagged(&[0.5, 2.0, 1.0, 1.0, 9.0]), vec![4]);
        // Even count: the median is the mean of the middle two, (1 + 3) / 2.
        assert_eq!(flagged(&[1.0, 3.0, 6.5, 1.0]), vec![2]);
        assert_eq!(flagged(&[1.0, 3.0, 5.9, 1.0]), Vec::<usize>::new());
    }

    #[test]
    fn two_runs_or_exact_fits_are_never_noisy() {
        assert_eq!(flagged(&[1.0, 100.0]), Vec::<usize>::new());
        assert_eq!(flagged(&[0.0, 0.0, 0.0]), Vec::<usize>::new());
    }

    #[test]
    fn the_warning_carries_the_run_and_the_median() {
        assert_eq!(
            noisy(&[0.5, 2.0, 1.0, 1.0, 9.0]),
            vec![Warning::NoisyRun {
                run: 4,
                residual_rms: 9.0,
                median_residual_rms: 1.0,
            }]
        );
    }
}
