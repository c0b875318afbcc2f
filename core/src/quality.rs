//! Quality flags: warnings about a calibration that is computed but weak.
//! They never change a number; each carries its statistic.
//!
//! * **ill_conditioned**: the design's condition number exceeds
//!   [`ILL_CONDITIONED`]; the terms named are those whose component in the
//!   unit right singular vector of the smallest singular value has magnitude
//!   at least 0.1 — the combination the positions barely separate (in 1 g,
//!   `a_i² + a_p² + a_o² = 1` makes `k0` with `kii`, `kpp`, `koo` such a
//!   combination, nearly singular once explicit components are rounded).
//! * **lack_of_fit**: the model misses something the repeated samples can
//!   see ([`crate::adequacy`]).
//! * **noisy_run**: run `j`'s scatter `s_j²` on `ν_j` degrees of freedom
//!   against the other runs pooled, `s²_(−j) = Σ_{l≠j} ν_l s_l² / Σ_{l≠j} ν_l`:
//!   flagged when `F = s_j² / s²_(−j)` exceeds the upper `NOISY_RUN_ALPHA / m`
//!   point of `F(ν_j, Σ_{l≠j} ν_l)` with `m` runs — a family-wise
//!   false-alarm rate of 1 % per submission. The scatter is the **pure
//!   error** when every run has replicate samples (`ν_pe,j ≥ 1` for every
//!   `j`, [`crate::adequacy`]): the samples' own scatter, which a run's bias
//!   shift cannot reach and which has `Σ_i (n_ij − 1)` degrees of freedom
//!   (4 for the paper's two samples at four positions) where the residuals
//!   have `P − p` (1 there) and almost no power. Otherwise it is the
//!   **residuals'**, `s_j² = Σ_i r_ij² / (P − p)`. Not tested with one run,
//!   without degrees of freedom, or when the other runs' scatter is zero.
//! * **implausibly_consistent_batch**: a batch's deviation of a coefficient
//!   below the floor of [`crate::fusion::consistency_floor`]; its weight
//!   used the floor.
//! * **unmodelled_term**: a term outside the model that explains the
//!   run-averaged values significantly better ([`crate::adequacy`]).

use serde::Serialize;

use crate::adequacy::{self, LackOfFit, PureError};
use crate::estimate::BatchSummary;
use crate::ftest::FTest;
use crate::fusion::scaled_norm;
use crate::identify::Identification;
use crate::term::{Term, TermMap};
use crate::tumble::{Calibration, TumbleTest, consistency_floors};

/// Condition number above which the design is flagged.
pub const ILL_CONDITIONED: f64 = 1e6;

/// Smallest component of the weakest direction that names a term.
pub const PARTICIPATION: f64 = 0.1;

/// Family-wise level of the noisy-run tests of one submission.
pub const NOISY_RUN_ALPHA: f64 = 0.01;

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
    /// The residuals exceed what the pure error explains.
    LackOfFit {
        /// `F`, `ν1`, `ν2`, p-value and level.
        #[serde(flatten)]
        test: FTest,
        /// The pooled pure error `s_pe`.
        pure_error_std: f64,
        /// The root of the lack-of-fit mean square.
        lack_of_fit_std: f64,
    },
    /// A run scatters significantly more than the others.
    NoisyRun {
        /// Run index (0-based).
        run: usize,
        /// `s_j² / s²_(−j)` and its test.
        #[serde(flatten)]
        test: FTest,
        /// Which scatter, and `s_j` and `s_(−j)`.
        #[serde(flatten)]
        scatter: Scatter,
    },
    /// A batch agrees better than its runs' own standard errors allow.
    ImplausiblyConsistentBatch {
        /// Batch index (0-based).
        batch: usize,
        /// The coefficient.
        term: Term,
        /// The batch's deviation `s_p`.
        std: f64,
        /// The floor its weight used.
        floor: f64,
    },
    /// A term outside the model would explain the data significantly better.
    UnmodelledTerm {
        /// The term.
        term: Term,
        /// Its partial F test.
        #[serde(flatten)]
        test: FTest,
    },
}

/// The scatter a noisy-run test compared (`test` in the warning), with
/// the run's `s_j` and the other runs' pooled `s_(−j)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "test", rename_all = "snake_case")]
pub enum Scatter {
    /// The pure error: the scatter of each position's repeated samples.
    PureError {
        /// `s_pe,j`.
        pure_error_std: f64,
        /// `s_pe,(−j)`.
        others_pure_error_std: f64,
    },
    /// The residuals of each run's fit.
    Residual {
        /// `s_j`.
        residual_std: f64,
        /// `s_(−j)`.
        others_residual_std: f64,
    },
}

/// The quality of a calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Quality {
    /// The design's condition number.
    pub condition_number: f64,
    /// The scatter of repeated samples.
    pub pure_error: PureError,
    /// The lack-of-fit test, or why it was not made.
    pub lack_of_fit: LackOfFit,
    /// Every warning, possibly none.
    pub warnings: Vec<Warning>,
}

/// Whether a condition number is flagged (strictly above [`ILL_CONDITIONED`]).
fn ill_conditioned(condition_number: f64) -> bool {
    condition_number > ILL_CONDITIONED
}

/// The noisy-run tests of `test`'s runs (see the module doc): on the
/// pure error when every run has replicates, else on the residuals.
fn noisy(test: &TumbleTest, runs: &[Identification]) -> Vec<Warning> {
    // (One run or none: either test has no other runs to pool, and is not
    // made.)
    let pure = adequacy::pure_error_norms(test);
    if pure.iter().all(|(_, dof)| *dof >= 1) {
        return noisy_by(&pure, |s, others| Scatter::PureError {
            pure_error_std: s,
            others_pure_error_std: others,
        });
    }
    let residual: Vec<(f64, usize)> = runs
        .iter()
        .map(|r| (scaled_norm(r.residuals.iter().copied()), r.dof))
        .collect();
    noisy_by(&residual, |s, others| Scatter::Residual {
        residual_std: s,
        others_residual_std: others,
    })
}

/// Each run's test against the others pooled, from every run's root sum
/// of squares and degrees of freedom `(‖·‖_j, ν_j)`; `scatter` names the
/// deviations `s_j = ‖·‖_j/√ν_j` and `s_(−j)`.
fn noisy_by(runs: &[(f64, usize)], scatter: impl Fn(f64, f64) -> Scatter) -> Vec<Warning> {
    // With one run, or none, or no degrees of freedom, the F test has a
    // zero degree of freedom and is not made (see `FTest::new`).
    let m = runs.len();
    let alpha = NOISY_RUN_ALPHA / m as f64;
    let mut out = Vec::new();
    for (run, (norm, dof)) in runs.iter().enumerate() {
        let others = || {
            runs.iter()
                .enumerate()
                .filter(|(l, _)| *l != run)
                .map(|(_, r)| *r)
        };
        let others_norm = scaled_norm(others().map(|(n, _)| n));
        let others_dof: usize = others().map(|(_, d)| d).sum();
        if let Some(test) =
            FTest::of_roots(*norm, *dof, others_norm, others_dof, alpha).filter(FTest::flagged)
        {
            out.push(Warning::NoisyRun {
                run,
                test,
                scatter: scatter(
                    norm / (*dof as f64).sqrt(),
                    others_norm / (others_dof as f64).sqrt(),
                ),
            });
        }
    }
    out
}

/// The batches whose deviation of a coefficient is below its floor.
fn implausibly_consistent(batches: &[BatchSummary], floors: &TermMap<f64>) -> Vec<Warning> {
    let mut out = Vec::new();
    for (batch, b) in batches.iter().enumerate() {
        for (term, floor) in floors.iter() {
            let std = b.std[term];
            if std < *floor {
                out.push(Warning::ImplausiblyConsistentBatch {
                    batch,
                    term,
                    std,
                    floor: *floor,
                });
            }
        }
    }
    out
}

/// The flags of a calibration of `test`.
pub fn assess(test: &TumbleTest, calibration: &Calibration) -> Quality {
    let design = test.design();
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
    let (pure_error, lack_of_fit) = adequacy::lack_of_fit(test, &calibration.runs);
    if let LackOfFit::Tested {
        test,
        pure_error_std,
        lack_of_fit_std,
    } = &lack_of_fit
        && test.flagged()
    {
        warnings.push(Warning::LackOfFit {
            test: *test,
            pure_error_std: *pure_error_std,
            lack_of_fit_std: *lack_of_fit_std,
        });
    }
    warnings.extend(noisy(test, &calibration.runs));
    warnings.extend(implausibly_consistent(
        &calibration.fused.batches,
        &consistency_floors(&calibration.runs),
    ));
    warnings.extend(
        adequacy::unmodelled_terms(test)
            .into_iter()
            .filter(|(_, f)| f.flagged())
            .map(|(term, test)| Warning::UnmodelledTerm { term, test }),
    );
    Quality {
        condition_number,
        pure_error,
        lack_of_fit,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_is_strict() {
        assert!(!ill_conditioned(ILL_CONDITIONED));
        assert!(ill_conditioned(1.000_000_1e6));
        assert!(!ill_conditioned(10.0));
    }

    /// A run's residuals and their degrees of freedom.
    fn run(residuals: &[f64], dof: usize) -> (Vec<f64>, usize) {
        (residuals.to_vec(), dof)
    }

    /// The residual noisy-run tests of runs given by their residuals.
    fn noisy_residuals(runs: &[(Vec<f64>, usize)]) -> Vec<Warning> {
        let norms: Vec<(f64, usize)> = runs
            .iter()
            .map(|(r, dof)| (scaled_norm(r.iter().copied()), *dof))
            .collect();
        noisy_by(&norms, |s, others| Scatter::Residual {
            residual_std: s,
            others_residual_std: others,
        })
    }

    /// Three runs of one degree of freedom, residual roots 1, 1 and 30:
    /// run 2 has F = 900 / ((1 + 1)/2) = 900 on (1, 2); its p-value is
    /// 1 − I(900/902; 1/2, 1) = 1 − √(900/902) ≈ 1.109e-3 < 0.01/3.
    #[test]
    fn a_run_is_noisy_beyond_the_bonferroni_point() {
        let runs = [run(&[1.0], 1), run(&[-1.0], 1), run(&[30.0], 1)];
        let w = noisy_residuals(&runs);
        match &w[..] {
            [
                Warning::NoisyRun {
                    run,
                    test,
                    scatter:
                        Scatter::Residual {
                            residual_std,
                            others_residual_std,
                        },
                },
            ] => {
                assert_eq!(*run, 2);
                assert_eq!((test.df1, test.df2), (1, 2));
                assert!((test.f - 900.0).abs() < 1e-9);
                let p = 1.0 - (900.0f64 / 902.0).sqrt();
                assert!((test.p_value - p).abs() < 1e-12, "{}", test.p_value);
                assert!((test.alpha - 0.01 / 3.0).abs() < 1e-18);
                assert_eq!(*residual_std, 30.0);
                assert_eq!(*others_residual_std, 1.0);
            }
            other => panic!("{other:?}"),
        }
        // F = 100: p = 1 − √(100/102) ≈ 9.9e-3, not below 0.01/3.
        assert!(noisy_residuals(&[run(&[1.0], 1), run(&[-1.0], 1), run(&[10.0], 1)]).is_empty());
    }

    /// Two runs of two degrees of freedom: roots 1 and 40 give F = 1600 on
    /// (2, 2), p = 1/(1 + F) ≈ 6.2e-4 < 0.01/2; the deviations are the
    /// roots over √2.
    #[test]
    fn two_runs_suffice_and_deviations_divide_by_their_degrees_of_freedom() {
        let w = noisy_residuals(&[run(&[1.0, 0.0], 2), run(&[0.0, 40.0], 2)]);
        match &w[..] {
            [
                Warning::NoisyRun {
                    run,
                    test,
                    scatter:
                        Scatter::Residual {
                            residual_std,
                            others_residual_std,
                        },
                },
            ] => {
                assert_eq!(*run, 1);
                assert!((test.p_value - 1.0 / 1601.0).abs() < 1e-12);
                assert!((residual_std - 40.0 / 2f64.sqrt()).abs() < 1e-12);
                assert!((others_residual_std - 1.0 / 2f64.sqrt()).abs() < 1e-15);
            }
            other => panic!("{other:?}"),
        }
    }

    /// Flagged strictly below the floor, per batch and term.
    #[test]
    fn a_batch_is_implausibly_consistent_strictly_below_its_floor() {
        let batch = |k0: f64, ki: f64| BatchSummary {
            runs: vec![0, 1],
            mean: TermMap(vec![(Term::K0, 0.0), (Term::Ki, 1.0)]),
            std: TermMap(vec![(Term::K0, k0), (Term::Ki, ki)]),
        };
        let floors = TermMap(vec![(Term::K0, 1e-6), (Term::Ki, 2e-6)]);
        let w = implausibly_consistent(&[batch(1e-6, 3e-6), batch(5e-7, 1.9e-6)], &floors);
        assert_eq!(
            w,
            [
                Warning::ImplausiblyConsistentBatch {
                    batch: 1,
                    term: Term::K0,
                    std: 5e-7,
                    floor: 1e-6
                },
                Warning::ImplausiblyConsistentBatch {
                    batch: 1,
                    term: Term::Ki,
                    std: 1.9e-6,
                    floor: 2e-6
                },
            ]
        );
        assert!(implausibly_consistent(&[batch(0.0, 0.0)], &TermMap(vec![])).is_empty());
    }

    /// Three runs of two samples at four positions (ν_pe = 4 each), run 2's
    /// samples 30 times as far apart: by hand, run j's pure-error sum of
    /// squares is Σ_i d_ij²/2 for sample differences d_ij, so with d = 0.01
    /// (runs 0, 1) and 0.3 (run 2) F = (4·0.09/2 / 4) / (8·1e-4/2 / 8) = 900
    /// on (4, 8); the residual test would see nothing, the runs' position
    /// means being alike. A run without replicates falls back to the
    /// residuals.
    #[test]
    fn the_pure_error_test_replaces_the_residual_test_when_every_run_has_replicates() {
        use crate::position::{Mount, Position};
        use crate::term::Model;
        use crate::tumble::Run;
        let positions: Vec<Position> = [0.0, 90.0, 180.0, 270.0]
            .map(|d| Position::from_angle(d, Mount::Pendulum, None))
            .to_vec();
        let run = |d: f64, shift: f64| {
            Run::from_samples(
                [0.3, 1.7, -0.5, -1.1]
                    .map(|y: f64| vec![y + shift - d / 2.0, y + shift + d / 2.0])
                    .to_vec(),
            )
        };
        let t = TumbleTest::new(
            Model::pendulum(),
            positions.clone(),
            vec![run(0.01, 0.0), run(0.01, 0.1), run(0.3, 0.2)],
        )
        .unwrap();
        let w = noisy(&t, &t.identify_runs());
        match &w[..] {
            [
                Warning::NoisyRun {
                    run: 2,
                    test,
                    scatter:
                        Scatter::PureError {
                            pure_error_std,
                            others_pure_error_std,
                        },
                },
            ] => {
                assert_eq!((test.df1, test.df2), (4, 8));
                assert!((test.f - 900.0).abs() < 1e-6, "{}", test.f);
                assert!((pure_error_std - (0.09f64 / 2.0).sqrt()).abs() < 1e-12);
                assert!((others_pure_error_std - (1e-4f64 / 2.0).sqrt()).abs() < 1e-12);
            }
            other => panic!("{other:?}"),
        }
        // Position means with y0 + y180 = y90 + y270 (residual e = 0) but
        // for a first position off by ±0.004 (e = ±0.001) in runs 0 and 1
        // and by 0.4 (e = 0.1) in run 2, read once a position: F = 0.01 /
        // 1e-6 = 1e4 on (1, 2), on the residuals.
        let means = |off: f64| [0.3 + off, 1.7, 0.1, -1.3];
        let replicated =
            |off: f64| Run::from_samples(means(off).map(|y| vec![y - 0.005, y + 0.005]).to_vec());
        let once = Run::from_samples(means(0.4).map(|y| vec![y]).to_vec());
        let t = TumbleTest::new(
            Model::pendulum(),
            positions,
            vec![replicated(0.004), replicated(-0.004), once],
        )
        .unwrap();
        match &noisy(&t, &t.identify_runs())[..] {
            [
                Warning::NoisyRun {
                    run: 2,
                    test,
                    scatter: Scatter::Residual { .. },
                },
            ] => {
                assert_eq!((test.df1, test.df2), (1, 2));
                assert!((test.f - 1e4).abs() < 1e-6 * 1e4, "{}", test.f);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn no_noisy_run_without_degrees_of_freedom_or_a_second_run() {
        assert!(noisy_residuals(&[run(&[30.0], 1)]).is_empty());
        assert!(noisy_residuals(&[run(&[0.0], 0), run(&[0.0], 0), run(&[0.0], 0)]).is_empty());
        // The others fit exactly: no finite ratio, no test.
        assert!(noisy_residuals(&[run(&[0.0], 1), run(&[0.0], 1), run(&[5.0], 1)]).is_empty());
        assert!(noisy_residuals(&[]).is_empty());
    }
}
