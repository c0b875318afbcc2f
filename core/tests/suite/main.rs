//! The core's tests, in one binary (one link per build: mutation testing
//! rebuilds it for every mutant).
//!
//! * [`adequacy`]: pure error, lack of fit, noisy runs, unmodelled terms,
//!   the model and explicit-indexing components and the consistency floor
//!   against a numpy/scipy reference;
//! * [`false_alarms`]: every warning's false-alarm rate on 2 000 clean
//!   simulated tumbles against its test's level;
//! * [`paper`]: every figure of the paper, to its printed digits;
//! * [`synthetic`]: noiseless tumbles of known truth, every identifiable term;
//! * [`properties`]: invariants under random inputs (proptest);
//! * [`extremes`]: scale-free numerics at the edges of `f64`;
//! * [`thermal`]: coefficients over temperature against numpy and scipy,
//!   and the degree selection's false-alarm rate;
//! * [`metrology`]: the uncertainty budget, decisions, as found, stability,
//!   temperature and quality flags against independent computations.

mod adequacy;
mod extremes;
mod false_alarms;
mod metrology;
mod paper;
mod properties;
mod synthetic;
mod thermal;
