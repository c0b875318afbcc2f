//! # accelcal-core
//!
//! The identification-and-fusion core of accelcal: pure functions over plain
//! data (no I/O, no async), shared by the HTTP service, the command line and
//! every test.
//!
//! The method is that of Pei & Wang, "Identification of Stationary Model for
//! Accelerometer Based on Data Fusion" (2005):
//!
//! 1. [`TumbleTest`]: positions of a dividing-head tumble ([`Position`],
//!    [`Mount`]), a [`Model`] of [`Term`]s, and repeated runs of samples
//!    or their summaries ([`Reading`]);
//! 2. per-run least-squares identification ([`identify::Design`]), with
//!    standard errors, residuals, and refusal of unidentifiable designs that
//!    names the inseparable terms;
//! 3. across runs, the arithmetic mean and batch-estimation fusion with their
//!    eq. 8 dispersions ([`estimate::estimate`], [`fusion`]);
//! 4. normalised IEEE-style values ([`Normalized`]) and compensation of raw
//!    outputs ([`Compensator`]);
//! 5. the metrology a lab signs: the uncertainty budget of each fused
//!    coefficient ([`uncertainty`]), conformity decisions against limits
//!    ([`decision`]), as found and stability over a sensor's history
//!    ([`history`]), temperature sensitivity ([`temperature`]) and
//!    coefficients over temperature ([`thermal`]), the model's
//!    adequacy — pure error, lack of fit, unmodelled terms ([`adequacy`]) —
//!    coverage factors from effective degrees of freedom ([`coverage`]) —
//!    and quality flags with their F tests ([`quality`], [`ftest`]);
//! 6. triads — three outputs at once, `u = b + S g` — as a view over three
//!    single-axis tumble tests sharing their positions ([`triad`]), or from
//!    the gravity magnitude alone ([`gravity_fit`], its budget
//!    [`gravity_budget`]).
//!
//! ```
//! use accelcal_core::{Model, Mount, Position, Run, Term, TumbleTest};
//!
//! let positions = [0.0, 90.0, 180.0, 270.0]
//!     .map(|deg| Position::from_angle(deg, Mount::Pendulum, None))
//!     .to_vec();
//! // U = 0.001 − 1.2·a_i + 0.006·a_p, four runs with a little noise.
//! let runs = (0..4)
//!     .map(|j| {
//!         let e = |k: u32| 1e-6 * f64::from((j * 7 + k * 3) % 5);
//!         Run::from_samples(vec![vec![0.007 + e(0)], vec![1.201 + e(1)], vec![-0.005 + e(2)], vec![-1.199 + e(3)]])
//!     })
//!     .collect();
//! let cal = TumbleTest::new(Model::pendulum(), positions, runs)?.calibrate(1)?;
//! let ki = cal.fused.coefficients.get(Term::Ki).unwrap();
//! assert!((ki + 1.2).abs() < 1e-5);
//! # Ok::<(), accelcal_core::Error>(())
//! ```

mod error;

/// The core's version, recorded with every result it computes: raised
/// whenever a number the core computes for the same input can change (0.2.0:
/// the design factorised by faer's SVD, and the adequacy tests; 0.3.0: each
/// expanded uncertainty's coverage factor from its effective degrees of
/// freedom, [`coverage`]; 0.4.0: `noisy_run` judged by the runs' pure
/// error when every run has replicate samples, [`quality`], and a batch of
/// equal runs weighted at the consistency floor rather than refused; 0.5.0:
/// designs factorised by one-sided Jacobi rotations, [`svd`], rather than
/// by faer's SVD, which can move a result's last digits).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

pub mod adequacy;
pub mod compensate;
pub mod coverage;
pub mod decision;
pub mod derived;
pub mod estimate;
pub mod ftest;
pub mod fusion;
pub mod gravity_budget;
pub mod gravity_fit;
pub mod history;
pub mod identify;
pub mod position;
pub mod quality;
pub mod reading;
pub mod static_intervals;
pub mod svd;
pub mod temperature;
pub mod term;
pub mod thermal;
pub mod triad;
pub mod tumble;
pub mod uncertainty;

pub use compensate::Compensator;
pub use derived::Normalized;
pub use error::{CompensateError, Error, FusionError};
pub use estimate::{Estimates, estimate};
pub use identify::{Design, Identification};
pub use position::{Gravity, Mount, Position, Rotation};
pub use reading::{Reading, Summary};
pub use term::{Model, Term, TermMap, UnknownTerm};
pub use tumble::{Calibration, Run, TumbleTest};
