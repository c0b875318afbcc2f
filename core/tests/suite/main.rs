//! The core's tests, in one binary (one link per build: mutation testing
//! rebuilds it for every mutant).
//!
//! * [`paper`]: every figure of the paper, to its printed digits;
//! * [`synthetic`]: noiseless tumbles of known truth, every identifiable term;
//! * [`properties`]: invariants under random inputs (proptest);
//! * [`extremes`]: scale-free numerics at the edges of `f64`;
//! * [`metrology`]: the uncertainty budget, decisions, as found, stability,
//!   temperature and quality flags against independent computations.

mod common;
mod extremes;
mod metrology;
mod paper;
mod properties;
mod synthetic;
