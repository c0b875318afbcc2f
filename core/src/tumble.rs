//! A tumble test — model, positions, repeated runs — and its calibration:
//! per-run identification, then mean and fusion across runs.
//!
//! Run `j` gives, for each position `r`, one or more samples (e.g. clockwise
//! and counter-clockwise), or their summary ([`Reading`]); the position's
//! value is their mean `y_jr = Σ_s u_jrs / n_jr`. Each run is identified on the same design
//! ([`Design`]), and each coefficient's per-run values are then combined by
//! [`estimate`](crate::estimate::estimate).

use serde::Serialize;

use crate::Error;
use crate::derived::Normalized;
use crate::estimate::{self, FusedEstimate, MeanEstimate};
use crate::fusion::{self, mean};
use crate::identify::{Design, Identification};
use crate::position::{Gravity, Position};
use crate::reading::{Fault, Reading};
use crate::term::{Model, TermMap};

/// One run of the tumble: for each position, its reading.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// `readings[r]` is the reading at position `r`.
    pub readings: Vec<Reading>,
}

impl Run {
    /// A run given as samples: `samples[r]` are position `r`'s.
    pub fn from_samples(samples: Vec<Vec<f64>>) -> Self {
        Run {
            readings: samples.into_iter().map(Reading::from).collect(),
        }
    }
}

/// A validated tumble test: its runs match its positions, every sample is
/// finite and the design identifies every term of the model.
#[derive(Clone, Debug)]
pub struct TumbleTest {
    positions: Vec<Position>,
    runs: Vec<Run>,
    design: Design,
}

impl TumbleTest {
    /// Checks and factorises a tumble test.
    ///
    /// Refuses a test without runs, a run without one reading per position,
    /// a run that is a copy of an earlier one ([`copied`]),
    /// a position without samples, a non-finite sample, an unusable summary
    /// ([`Reading::check`]), and an unidentifiable design (see
    /// [`Design::new`]).
    pub fn new(model: Model, positions: Vec<Position>, runs: Vec<Run>) -> Result<Self, Error> {
        let test = Self::of_axis(model, positions, runs)?;
        if let Some((run, copy_of)) = copied(&test.runs) {
            return Err(Error::CopiedRun { run, copy_of });
        }
        Ok(test)
    }

    /// As [`TumbleTest::new`] but without the copy check: one axis of a
    /// triad, whose runs are copies only if all three axes' are (a
    /// quantised axis may read the same counts every run).
    pub(crate) fn of_axis(
        model: Model,
        positions: Vec<Position>,
        runs: Vec<Run>,
    ) -> Result<Self, Error> {
        if runs.is_empty() {
            return Err(Error::NoRuns);
        }
        for (run, r) in runs.iter().enumerate() {
            if r.readings.len() != positions.len() {
                return Err(Error::ReadingCount {
                    run,
                    expected: positions.len(),
                    found: r.readings.len(),
                });
            }
            for (position, reading) in r.readings.iter().enumerate() {
                reading.check().map_err(|fault| match fault {
                    Fault::Empty => Error::NoSamples { run, position },
                    Fault::NonFinite(sample) => Error::NonFiniteSample {
                        run,
                        position,
                        sample,
                    },
                    fault => Error::InvalidSummary {
                        run,
                        position,
                        fault,
                    },
                })?;
            }
        }
        let gravity: Vec<Gravity> = positions.iter().map(|p| p.a).collect();
        let design = Design::new(&model, &gravity)?;
        Ok(TumbleTest {
            positions,
            runs,
            design,
        })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        self.design.model()
    }

    /// The positions.
    pub fn positions(&self) -> &[Position] {
        &self.positions
    }

    /// The runs.
    pub fn runs(&self) -> &[Run] {
        &self.runs
    }

    /// The factorised design.
    pub fn design(&self) -> &Design {
        &self.design
    }

    /// Each run's position values `ȳ_jr`, the means of its samples.
    pub fn position_values(&self) -> Vec<Vec<f64>> {
        self.runs
            .iter()
            .map(|run| run.readings.iter().map(Reading::mean).collect())
            .collect()
    }

    /// The run-averaged position values `x̃_r = Σ_j ȳ_jr / m` over the `m`
    /// runs: what a systematic misfit, the same in every run, survives into.
    pub fn averaged_values(&self) -> Vec<f64> {
        let values = self.position_values();
        (0..self.positions.len())
            .map(|r| mean(&values.iter().map(|y| y[r]).collect::<Vec<_>>()))
            .collect()
    }

    /// The least-squares fit of the run-averaged values (see
    /// [`averaged_values`](Self::averaged_values)).
    pub fn averaged_fit(&self) -> Identification {
        self.design.solve(&self.averaged_values())
    }

    /// Identifies every run separately.
    pub fn identify_runs(&self) -> Vec<Identification> {
        self.position_values()
            .iter()
            .map(|y| self.design.solve(y))
            .collect()
    }

    /// Identifies every run, then estimates every coefficient across runs
    /// with `batches` batches, each batch's weight floored by the runs' own
    /// standard errors ([`consistency_floors`]). A single run is its own
    /// estimate ([`estimate::single_run`]; `batches` is then not used), and
    /// needs a spare position for its standard errors.
    pub fn calibrate(&self, batches: usize) -> Result<Calibration, Error> {
        let runs = self.identify_runs();
        for run in &runs {
            estimate::finite(&run.coefficients, "per-run coefficient")?;
            if let Some(se) = &run.std_errors {
                estimate::finite(se, "per-run standard error")?;
            }
        }
        let values = TermMap(
            self.model()
                .terms()
                .iter()
                .map(|t| {
                    let xs = runs
                        .iter()
                        .map(|r| *r.coefficients.get(*t).expect("model term"))
                        .collect();
                    (*t, xs)
                })
                .collect(),
        );
        let est = match &runs[..] {
            // One run: its own coefficients and standard errors, if any.
            [run] => {
                let se = run.std_errors.as_ref().ok_or(Error::SingleRunWithoutDof {
                    positions: self.positions.len(),
                    terms: self.model().len(),
                })?;
                estimate::single_run(&run.coefficients, se, run.dof)
            }
            _ => estimate::estimate_with_floors(&values, batches, &consistency_floors(&runs))?,
        };
        Ok(Calibration {
            condition_number: self.design.condition_number(),
            normalized: Normalized::from_coefficients(&est.fused.coefficients),
            runs,
            mean: est.mean,
            fused: est.fused,
        })
    }
}

/// The first run whose readings equal an earlier run's, sample for sample
/// and in number (`-0.0` equal to `0.0`), with that run: `(run, copy_of)`.
/// A comparison stops at the first reading that differs, so m distinct
/// runs cost about m²/2 comparisons of a few numbers.
pub fn copied<T: PartialEq>(runs: &[T]) -> Option<(usize, usize)> {
    for (j, later) in runs.iter().enumerate().skip(1) {
        if let Some(i) = runs[..j].iter().position(|earlier| earlier == later) {
            return Some((j, i));
        }
    }
    None
}

/// Each coefficient's floor of a batch deviation (see
/// [`fusion::consistency_floor`]) from the runs' own standard errors; no
/// floor when a run has none (no spare positions).
pub fn consistency_floors(runs: &[Identification]) -> TermMap<f64> {
    let Some(first) = runs.first() else {
        return TermMap(Vec::new());
    };
    TermMap(
        first
            .coefficients
            .iter()
            .filter_map(|(t, _)| {
                let se: Option<Vec<f64>> = runs
                    .iter()
                    .map(|r| r.std_errors.as_ref().and_then(|s| s.get(t).copied()))
                    .collect();
                Some((t, fusion::consistency_floor(&se?)))
            })
            .collect(),
    )
}

/// The outcome of calibrating a tumble test.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Calibration {
    /// 2-norm condition number of the design.
    pub condition_number: f64,
    /// Per-run identification, in submission order.
    pub runs: Vec<Identification>,
    /// Arithmetic mean across runs with eq. 8 dispersion.
    pub mean: MeanEstimate,
    /// Batch-estimation fusion across runs with eq. 8 dispersion.
    pub fused: FusedEstimate,
    /// Normalised values derived from the fused coefficients.
    pub normalized: Normalized,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::position::Mount;

    fn four() -> Vec<Position> {
        [0.0, 90.0, 180.0, 270.0]
            .iter()
            .map(|d| Position::from_angle(*d, Mount::Pendulum, None))
            .collect()
    }

    /// Only a run equal to an earlier one sample for sample is a copy:
    /// the same samples in another order, one sample more, or a summary of
    /// the same samples are not.
    #[test]
    fn a_copied_run_is_named_with_the_run_it_repeats() {
        let mk = |runs: Vec<Run>| TumbleTest::new(Model::pendulum(), four(), runs).map(|_| ());
        let run =
            |first: Vec<f64>| Run::from_samples(vec![first, vec![2.0], vec![-0.5], vec![-2.0]]);
        assert_eq!(
            mk(vec![
                run(vec![0.1, 0.3]),
                run(vec![0.3, 0.1]),
                run(vec![0.1, 0.3, 0.3]),
                run(vec![0.3, 0.1]),
            ]),
            Err(Error::CopiedRun { run: 3, copy_of: 1 })
        );
        // −0 is 0: the same reading.
        assert_eq!(
            mk(vec![run(vec![0.0]), run(vec![-0.0])]),
            Err(Error::CopiedRun { run: 1, copy_of: 0 })
        );
        let mut summary = run(vec![0.1, 0.3]);
        summary.readings[0] = Reading::Summary(crate::reading::Summary {
            mean: 0.2,
            std: 0.1f64.hypot(0.1),
            count: 2,
        });
        assert!(mk(vec![run(vec![0.1, 0.3]), summary]).is_ok());
    }

    #[test]
    fn shape_errors_point_at_run_position_and_sample() {
        let ok = vec![vec![1.0]; 4];
        let mk = |runs: Vec<Vec<Vec<f64>>>| {
            TumbleTest::new(
                Model::pendulum(),
                four(),
                runs.into_iter().map(Run::from_samples).collect(),
            )
            .map(|_| ())
        };
        assert_eq!(mk(vec![]), Err(Error::NoRuns));
        assert_eq!(
            mk(vec![ok.clone(), vec![vec![1.0]; 3]]),
            Err(Error::ReadingCount {
                run: 1,
                expected: 4,
                found: 3
            })
        );
        let mut empty = ok.clone();
        empty[2] = vec![];
        assert_eq!(
            mk(vec![ok.clone(), empty]),
            Err(Error::NoSamples {
                run: 1,
                position: 2
            })
        );
        let mut nan = ok.clone();
        nan[3] = vec![1.0, f64::INFINITY];
        assert_eq!(
            mk(vec![nan]),
            Err(Error::NonFiniteSample {
                run: 0,
                position: 3,
                sample: 1
            })
        );
        let mut summary = Run::from_samples(ok.clone());
        summary.readings[1] = Reading::Summary(crate::Summary {
            mean: 1.0,
            std: 0.5,
            count: 1,
        });
        assert_eq!(
            TumbleTest::new(Model::pendulum(), four(), vec![summary]).map(|_| ()),
            Err(Error::InvalidSummary {
                run: 0,
                position: 1,
                fault: Fault::SpreadOfOne
            })
        );
    }

    #[test]
    fn a_test_keeps_its_model_positions_and_runs() {
        let model = Model::new(vec![crate::Term::K0, crate::Term::Kp]).unwrap();
        let runs = vec![Run::from_samples(vec![
            vec![1.0],
            vec![2.0],
            vec![3.0],
            vec![4.0],
        ])];
        let t = TumbleTest::new(model.clone(), four(), runs.clone()).unwrap();
        assert_eq!(t.model(), &model);
        assert_eq!(t.positions(), four().as_slice());
        assert_eq!(t.runs(), runs.as_slice());
        assert_eq!(t.design().positions(), 4);
    }

    #[test]
    fn position_value_is_the_mean_of_its_samples() {
        let t = TumbleTest::new(
            Model::pendulum(),
            four(),
            vec![Run::from_samples(vec![
                vec![1.0, 3.0],
                vec![5.0],
                vec![-1.0, -2.0, -3.0],
                vec![0.0],
            ])],
        )
        .unwrap();
        assert_eq!(t.position_values(), [[2.0, 5.0, -2.0, 0.0]]);
        let id = &t.identify_runs()[0];
        // kp = (U0 − U180)/2 = (2 − (−2))/2
        assert!((id.coefficients.get(crate::Term::Kp).unwrap() - 2.0).abs() < 1e-15);
    }

    #[test]
    fn a_summary_is_its_mean() {
        let summary = |mean, std, count| Reading::Summary(crate::Summary { mean, std, count });
        let t = TumbleTest::new(
            Model::pendulum(),
            four(),
            vec![Run {
                readings: vec![
                    summary(2.0, 1.4, 2),
                    Reading::from(vec![5.0]),
                    summary(-2.0, 1.0, 3),
                    summary(0.0, 0.0, 1),
                ],
            }],
        )
        .unwrap();
        assert_eq!(t.position_values(), [[2.0, 5.0, -2.0, 0.0]]);
    }
}
