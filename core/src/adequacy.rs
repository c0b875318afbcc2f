//! Is the model adequate for the data? Pure error, the lack-of-fit test, the
//! model component of the uncertainty, and partial F tests of the terms the
//! model leaves out.
//!
//! Run `j`, position `i`, samples `x_ijk` (`k = 1..n_ij`), position mean
//! `x̄_ij`, residual `r_ij` of run `j`'s least-squares fit, `P` positions, `p`
//! model terms, `m` runs:
//!
//! * **Pure error** of run `j`, over positions with `n_ij ≥ 2`:
//!   `s²_pe,j = Σ_i Σ_k (x_ijk − x̄_ij)² / Σ_i (n_ij − 1)`; pooled over runs,
//!   `s²_pe = Σ_j Σ_i Σ_k (…)² / Σ_j Σ_i (n_ij − 1)`, with `ν_pe` that
//!   denominator. It is the scatter of repeated samples, which no model
//!   error can reach. A position given as a summary (mean, `s_ij`, `n_ij`)
//!   adds `s_ij²·(n_ij − 1)` to the sum ([`crate::reading`]).
//! * **Lack of fit** (pooled): `F = [Σ_j Σ_i n_ij·r_ij² / Σ_j (P − p)] / s²_pe`
//!   on `ν1 = Σ_j (P − p)`, `ν2 = ν_pe`; flagged when `F` exceeds the upper
//!   [`LACK_OF_FIT_ALPHA`] point of `F(ν1, ν2)`. Not computed without
//!   `ν1 ≥ 1` and `ν2 ≥ 1`, or when `s²_pe = 0` ([`NotTested`]).
//! * **Model uncertainty**: when lack of fit is flagged, each coefficient's
//!   standard error from one least-squares fit to the run-averaged values
//!   `x̃_i = Σ_j x̄_ij / m`, residual variance `Σ_i r̃_i² / (P − p)`; 0
//!   otherwise. A misfit that is the same in every run is invisible to the
//!   run-to-run scatter fusion sees; this is where it shows.
//! * **Unmodelled term** `t`, for each term not in the model whose addition
//!   keeps the design identifiable and leaves `P − p − 1 ≥ 1`: on the
//!   run-averaged values, `F_t = (RSS − RSS_t) / (RSS_t / (P − p − 1))` on
//!   `(1, P − p − 1)`, flagged beyond the upper [`UNMODELLED_ALPHA`] point.
//!   `RSS_t` comes from the model's design widened by the term's column
//!   ([`Design::widened`](crate::identify::Design::widened)), not from a
//!   second factorisation.
//!
//! Sums of squares are squares of scaled norms ([`scaled_norm`]) and the
//! statistics are formed as ratios of norms, so they do not depend on the
//! data's scale and neither underflow nor overflow for outputs near the ends
//! of `f64`.

use serde::Serialize;

use crate::Term;
use crate::ftest::FTest;
use crate::fusion::scaled_norm;
use crate::identify::Identification;
use crate::position::Gravity;
use crate::reading::Reading;
use crate::term::{Model, TermMap};
use crate::tumble::TumbleTest;
use nalgebra::DVector;

/// Level of the lack-of-fit test (the upper 0.1 % point).
pub const LACK_OF_FIT_ALPHA: f64 = 0.001;

/// Level of each unmodelled-term test (the upper 0.1 % point).
pub const UNMODELLED_ALPHA: f64 = 0.001;

/// A standard deviation with its degrees of freedom.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Spread {
    /// `√(sum of squares / dof)`; `None` without degrees of freedom.
    pub std: Option<f64>,
    /// The degrees of freedom.
    pub dof: usize,
}

impl Spread {
    fn of(norm: f64, dof: usize) -> Self {
        Spread {
            std: (dof > 0).then(|| norm / (dof as f64).sqrt()),
            dof,
        }
    }
}

/// The pure error: per run and pooled.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PureError {
    /// Pooled over the runs: `s_pe` and `ν_pe`.
    #[serde(flatten)]
    pub pooled: Spread,
    /// Per run, in run order.
    pub runs: Vec<Spread>,
}

/// The pure error of a tumble test, with the root of its pooled sum of
/// squares (for [`lack_of_fit`]).
fn pure_error_norm(test: &TumbleTest) -> (PureError, f64) {
    let (norms, runs): (Vec<f64>, Vec<Spread>) = pure_error_norms(test)
        .into_iter()
        .map(|(norm, dof)| (norm, Spread::of(norm, dof)))
        .unzip();
    let dof = runs.iter().map(|r| r.dof).sum();
    let norm = scaled_norm(norms.iter().copied());
    (
        PureError {
            pooled: Spread::of(norm, dof),
            runs,
        },
        norm,
    )
}

/// Each run's pure error as the root of its sum of squares and its
/// degrees of freedom, `(‖x_ijk − x̄_ij‖, Σ_i (n_ij − 1))`, in run order.
pub fn pure_error_norms(test: &TumbleTest) -> Vec<(f64, usize)> {
    test.runs()
        .iter()
        .map(|run| {
            let roots = run.readings.iter().map(Reading::deviation_norm);
            let dof = run.readings.iter().map(|r| r.dof() as usize).sum();
            (scaled_norm(roots), dof)
        })
        .collect()
}

/// The pure error of a tumble test.
pub fn pure_error(test: &TumbleTest) -> PureError {
    pure_error_norm(test).0
}

/// Why lack of fit was not tested.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NotTested {
    /// As many positions as terms: every run fits exactly (`ν1 = 0`).
    NoResidualDof,
    /// No position holds two samples in any run (`ν2 = 0`).
    NoReplicates,
    /// The repeated samples are identical (`s²_pe = 0`), or scatter too
    /// little for the ratio to be a finite number.
    NoScatter,
}

/// The lack-of-fit test of a calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum LackOfFit {
    /// Computed.
    Tested {
        /// `F`, `ν1`, `ν2`, its p-value and the level.
        #[serde(flatten)]
        test: FTest,
        /// `s_pe`, the pooled pure error.
        pure_error_std: f64,
        /// `√(Σ_j Σ_i n_ij·r_ij² / ν1)`, the numerator's root.
        lack_of_fit_std: f64,
    },
    /// Not computed, and why.
    NotTested {
        /// The reason.
        reason: NotTested,
    },
}

impl LackOfFit {
    /// Whether lack of fit was tested and found.
    pub fn flagged(&self) -> bool {
        matches!(self, LackOfFit::Tested { test, .. } if test.flagged())
    }
}

/// The pure error and the lack-of-fit test of `test`, whose runs were
/// identified as `runs`.
pub fn lack_of_fit(test: &TumbleTest, runs: &[Identification]) -> (PureError, LackOfFit) {
    let (pure, pe_norm) = pure_error_norm(test);
    let not = |reason| LackOfFit::NotTested { reason };
    let df1: usize = runs.iter().map(|r| r.dof).sum();
    let df2 = pure.pooled.dof;
    if df1 == 0 {
        return (pure, not(NotTested::NoResidualDof));
    }
    if df2 == 0 {
        return (pure, not(NotTested::NoReplicates));
    }
    // √(Σ_j Σ_i n_ij·r_ij²)
    let weighted = test.runs().iter().zip(runs).flat_map(|(run, id)| {
        run.readings
            .iter()
            .zip(&id.residuals)
            .map(|(reading, r)| (reading.count() as f64).sqrt() * r)
    });
    let lof_norm = scaled_norm(weighted);
    let outcome = match FTest::of_roots(lof_norm, df1, pe_norm, df2, LACK_OF_FIT_ALPHA) {
        Some(test) => LackOfFit::Tested {
            test,
            pure_error_std: pe_norm / (df2 as f64).sqrt(),
            lack_of_fit_std: lof_norm / (df1 as f64).sqrt(),
        },
        None => not(NotTested::NoScatter),
    };
    (pure, outcome)
}

/// The budget's `model` component of every term: the standard errors of the
/// fit to the run-averaged values when `lack_of_fit` is flagged, otherwise
/// none (0 for every term).
pub fn model_uncertainty(test: &TumbleTest, lack_of_fit: &LackOfFit) -> TermMap<f64> {
    if !lack_of_fit.flagged() {
        return TermMap(Vec::new());
    }
    test.averaged_fit()
        .std_errors
        .unwrap_or_else(|| TermMap(Vec::new()))
}

/// The partial F test of every term the model leaves out whose addition keeps
/// the design identifiable with a residual degree of freedom to spare, in
/// [`Term::ALL`] order.
pub fn unmodelled_terms(test: &TumbleTest) -> Vec<(Term, FTest)> {
    let design = test.design();
    let model = design.model();
    let positions = design.positions();
    // P − p − 1; without a spare degree of freedom no F test is made.
    let df2 = positions.saturating_sub(model.len() + 1);
    if df2 == 0 {
        return Vec::new();
    }
    let gravity: Vec<Gravity> = test.positions().iter().map(|p| p.a).collect();
    let residuals = DVector::from_vec(design.solve(&test.averaged_values()).residuals);
    let base = scaled_norm(residuals.iter().copied());
    Term::ALL
        .into_iter()
        .filter(|t| model.index_of(*t).is_none())
        .filter_map(|t| {
            let mut terms = model.terms().to_vec();
            terms.push(t);
            Model::new(terms).ok()?;
            let column: Vec<f64> = gravity.iter().map(|a| t.regressor(a)).collect();
            let z = design.widened(&column)?;
            // The widened fit's residual: r − ẑ·(ẑᵀ·r).
            let wider = &residuals - &z * z.dot(&residuals);
            let ratio = base / scaled_norm(wider.iter().copied());
            // (RSS − RSS_t) / (RSS_t / ν2) = ((‖r‖/‖r_t‖)² − 1)·ν2, ≥ 0 up to rounding.
            let f = ((ratio * ratio - 1.0) * df2 as f64).max(0.0);
            Some((t, FTest::new(f, 1, df2, UNMODELLED_ALPHA)?))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::position::{Mount, Position};
    use crate::tumble::Run;

    fn four() -> Vec<Position> {
        [0.0, 90.0, 180.0, 270.0]
            .map(|d| Position::from_angle(d, Mount::Pendulum, None))
            .to_vec()
    }

    fn test_of(positions: Vec<Position>, runs: Vec<Vec<Vec<f64>>>) -> TumbleTest {
        let runs = runs.into_iter().map(Run::from_samples).collect();
        TumbleTest::new(Model::pendulum(), positions, runs).unwrap()
    }

    /// By hand: run 0 has positions with samples {1, 3} (SS 2, dof 1),
    /// {5} (dof 0), {0, 0, 3} (SS 6, dof 2), {2, 2}: SS 8 on 4 dof. Run 1:
    /// {1, 2} (SS 0.5), the rest single: SS 0.5 on 1 dof.
    #[test]
    fn pure_error_by_hand() {
        let t = test_of(
            four(),
            vec![
                vec![
                    vec![1.0, 3.0],
                    vec![5.0],
                    vec![0.0, 0.0, 3.0],
                    vec![2.0, 2.0],
                ],
                vec![vec![1.0, 2.0], vec![5.0], vec![1.0], vec![2.0]],
            ],
        );
        let pe = pure_error(&t);
        assert_eq!(pe.runs[0].dof, 4);
        assert!((pe.runs[0].std.unwrap() - 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(pe.runs[1].dof, 1);
        assert!((pe.runs[1].std.unwrap() - 0.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(pe.pooled.dof, 5);
        assert!((pe.pooled.std.unwrap() - (8.5f64 / 5.0).sqrt()).abs() < 1e-15);
    }

    /// Four positions, model k0 ki kp: one residual degree of freedom per
    /// run, residual ±e with e = (y0 − y90 + y180 − y270)/4, so
    /// Σ n·r² = n·4e² on ν1 = 1 per run.
    #[test]
    fn lack_of_fit_by_hand() {
        // Position means 0.3, 1.7, −0.5, −1.1 (e = −0.2); two samples
        // ±0.01 apart around each: SS = 4·2·0.01² on 4 dof.
        let run = |shift: f64| {
            [0.3, 1.7, -0.5, -1.1]
                .map(|y: f64| vec![y + shift - 0.01, y + shift + 0.01])
                .to_vec()
        };
        let t = test_of(four(), vec![run(0.0), run(0.2)]);
        let ids = t.identify_runs();
        let (pe, lof) = lack_of_fit(&t, &ids);
        assert_eq!(pe.pooled.dof, 8);
        let s2_pe: f64 = 2.0 * 4.0 * 2.0 * 1e-4 / 8.0;
        let ms_lof: f64 = 2.0 * (2.0 * 4.0 * 0.2 * 0.2) / 2.0;
        match lof {
            LackOfFit::Tested {
                test,
                pure_error_std,
                lack_of_fit_std,
            } => {
                assert_eq!((test.df1, test.df2), (2, 8));
                assert!(
                    (test.f - ms_lof / s2_pe).abs() < 1e-9 * test.f,
                    "{}",
                    test.f
                );
                assert!((pure_error_std - s2_pe.sqrt()).abs() < 1e-15);
                assert!((lack_of_fit_std - ms_lof.sqrt()).abs() < 1e-14);
                assert!(test.flagged());
                assert_eq!(test.alpha, LACK_OF_FIT_ALPHA);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn lack_of_fit_says_why_it_was_not_tested() {
        let single = |d: f64| vec![vec![0.3 + d], vec![1.7], vec![-0.5], vec![-1.1]];
        let t = test_of(four(), vec![single(0.0), single(0.01)]);
        let (_, lof) = lack_of_fit(&t, &t.identify_runs());
        assert_eq!(
            lof,
            LackOfFit::NotTested {
                reason: NotTested::NoReplicates
            }
        );
        assert!(!lof.flagged());
        let same = |d: f64| {
            vec![
                vec![0.3 + d, 0.3 + d],
                vec![1.7, 1.7],
                vec![-0.5, -0.5],
                vec![-1.1, -1.1],
            ]
        };
        let t = test_of(four(), vec![same(0.0), same(0.01)]);
        let (_, lof) = lack_of_fit(&t, &t.identify_runs());
        assert_eq!(
            lof,
            LackOfFit::NotTested {
                reason: NotTested::NoScatter
            }
        );
        let exact = TumbleTest::new(
            Model::new(vec![Term::K0, Term::Ki, Term::Kp, Term::Kii]).unwrap(),
            four(),
            vec![Run::from_samples(vec![
                vec![0.3, 0.4],
                vec![1.7, 1.6],
                vec![-0.5, -0.4],
                vec![-1.1, -1.0],
            ])],
        )
        .unwrap();
        let (_, lof) = lack_of_fit(&exact, &exact.identify_runs());
        assert_eq!(
            lof,
            LackOfFit::NotTested {
                reason: NotTested::NoResidualDof
            }
        );
    }

    #[test]
    fn the_model_component_is_zero_unless_lack_of_fit_is_flagged() {
        let positions: Vec<Position> = (0..8)
            .map(|k| Position::from_angle(45.0 * f64::from(k), Mount::Pendulum, None))
            .collect();
        // Outputs 1 + 0.5·a_i² (unmodelled), two samples ±1e-6 apart; the
        // second run offset by 1e-6.
        let run = |positions: &[Position], d: f64| {
            positions
                .iter()
                .map(|p| {
                    let y = 1.0 + 0.5 * p.a.i * p.a.i + d;
                    vec![y - 1e-6, y + 1e-6]
                })
                .collect::<Vec<_>>()
        };
        let t = test_of(
            positions.clone(),
            vec![run(&positions, 0.0), run(&positions, 1e-6)],
        );
        let (_, lof) = lack_of_fit(&t, &t.identify_runs());
        assert!(lof.flagged());
        let model = model_uncertainty(&t, &lof);
        assert_eq!(model, t.averaged_fit().std_errors.unwrap());
        assert!(model.iter().all(|(_, se)| *se > 1e-3));
        let clean = LackOfFit::NotTested {
            reason: NotTested::NoScatter,
        };
        assert!(model_uncertainty(&t, &clean).is_empty());
    }

    #[test]
    fn an_unmodelled_square_is_found_and_nothing_else_is_flagged() {
        let positions: Vec<Position> = (0..8)
            .map(|k| Position::from_angle(45.0 * f64::from(k), Mount::Pendulum, None))
            .collect();
        let wiggle = [1.0, -0.5, 0.25, 0.75, -1.0, 0.5, -0.25, -0.75];
        let run = |j: usize| {
            positions
                .iter()
                .enumerate()
                .map(|(r, p)| vec![1.0 + 0.5 * p.a.i * p.a.i + 1e-6 * wiggle[(r + j) % 8]])
                .collect::<Vec<_>>()
        };
        let t = test_of(positions.clone(), vec![run(0), run(3)]);
        let tests = unmodelled_terms(&t);
        let flagged: Vec<Term> = tests
            .iter()
            .filter(|(_, f)| f.flagged())
            .map(|(t, _)| *t)
            .collect();
        // kpp would explain it as well (a_p² = 1 − a_i² on a pendulum tumble).
        assert!(flagged.contains(&Term::Kii), "{tests:?}");
        assert!(!flagged.contains(&Term::Kpi), "{tests:?}");
        // a_o = 0 on a pendulum tumble: ko is never testable.
        assert!(tests.iter().all(|(t, _)| *t != Term::Ko));
        assert!(tests.iter().all(|(_, f)| (f.df1, f.df2) == (1, 4)));
    }

    #[test]
    fn no_unmodelled_test_without_a_spare_degree_of_freedom() {
        let t = test_of(
            four(),
            vec![vec![vec![0.3], vec![1.7], vec![-0.5], vec![-1.1]]],
        );
        assert!(unmodelled_terms(&t).is_empty());
    }
}
