//! Typed refusals of the core.
//!
//! Every variant carries the indices (run, position, sample, batch) and terms a
//! caller needs to point a user at the offending part of their input; indices
//! are 0-based, as in JSON pointers.

use std::fmt;

use crate::term::Term;

/// Why the core refused a model, a tumble test or a set of values.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The model lists no terms.
    #[error("the model has no terms")]
    EmptyModel,
    /// A term appears more than once in the model.
    #[error("term `{term}` appears more than once in the model (again at index {index})")]
    DuplicateTerm {
        /// Index of the repeated occurrence.
        index: usize,
        /// The repeated term.
        term: Term,
    },
    /// The tumble has no positions.
    #[error("the tumble has no positions")]
    NoPositions,
    /// A position's gravity component is NaN or infinite.
    #[error("position {position}: gravity component {axis} is not a finite number")]
    NonFiniteGravity {
        /// Position index.
        position: usize,
        /// Axis index (0 = a_i, 1 = a_p, 2 = a_o).
        axis: usize,
    },
    /// The design's columns are (numerically) dependent, or there are fewer
    /// positions than terms: these terms cannot be separated.
    #[error(
        "terms {} cannot be separated by this tumble ({positions} positions, {columns} terms, rank {rank})",
        TermList(terms)
    )]
    RankDeficient {
        /// The terms involved in the design's null space.
        terms: Vec<Term>,
        /// Number of positions (rows).
        positions: usize,
        /// Number of terms (columns).
        columns: usize,
        /// Numerical rank of the design.
        rank: usize,
    },
    /// The test has no runs.
    #[error("the test has no runs")]
    NoRuns,
    /// A run does not give one reading per position.
    #[error("run {run} has readings for {found} positions, expected {expected}")]
    ReadingCount {
        /// Run index.
        run: usize,
        /// Number of positions.
        expected: usize,
        /// Number of readings given.
        found: usize,
    },
    /// A run gives no sample at a position.
    #[error("run {run}, position {position}: no samples")]
    NoSamples {
        /// Run index.
        run: usize,
        /// Position index.
        position: usize,
    },
    /// A sample is NaN or infinite.
    #[error("run {run}, position {position}, sample {sample}: not a finite number")]
    NonFiniteSample {
        /// Run index.
        run: usize,
        /// Position index.
        position: usize,
        /// Sample index.
        sample: usize,
    },
    /// A summary that cannot be used.
    #[error("run {run}, position {position}: {fault}")]
    InvalidSummary {
        /// Run index.
        run: usize,
        /// Position index.
        position: usize,
        /// What is wrong with it.
        fault: crate::reading::Fault,
    },
    /// No coefficient values were given to fuse.
    #[error("no coefficient values were given")]
    NoValues,
    /// Coefficients given for fusion do not all have the same number of runs.
    #[error("coefficient `{term}` has {found} values, expected {expected} (one per run)")]
    ValueCount {
        /// The coefficient with the wrong count.
        term: Term,
        /// The count of the first coefficient.
        expected: usize,
        /// This coefficient's count.
        found: usize,
    },
    /// A computed quantity of a coefficient is NaN or infinite: the input is
    /// too extreme for double precision. Never stored or served.
    #[error("coefficient `{term}`: the {quantity} is not a finite number; rescale the outputs")]
    NonFiniteResult {
        /// The coefficient concerned.
        term: Term,
        /// Which quantity (`coefficient`, `standard error`, `dispersion`, …).
        quantity: &'static str,
    },
    /// A run whose readings are those of an earlier run, element by element
    /// and in number: most likely the same data sent twice.
    #[error(
        "run {run} is a copy of run {copy_of}: every reading holds the same samples, in the same \
         number; a repeated tumble never reads identically, so send each run's own data once"
    )]
    CopiedRun {
        /// The later run, from 0.
        run: usize,
        /// The run it repeats, from 0.
        copy_of: usize,
    },
    /// A single run with as many positions as terms: it fits exactly, so it
    /// has no standard errors to stand for the fused ones.
    #[error(
        "a single run of {positions} positions and {terms} terms fits exactly and gives no \
         standard errors: add positions, or submit two runs or more"
    )]
    SingleRunWithoutDof {
        /// Number of positions.
        positions: usize,
        /// Number of model terms.
        terms: usize,
    },
    /// Batch-estimation fusion of one coefficient failed.
    #[error("coefficient `{term}`: {source}")]
    Fusion {
        /// The coefficient whose values could not be fused.
        term: Term,
        /// What went wrong.
        source: FusionError,
    },
}

/// Why a set of per-run values could not be fused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FusionError {
    /// Zero batches were asked for.
    #[error("the number of batches must be at least 1")]
    NoBatches,
    /// A batch would hold fewer than two runs, so it has no standard deviation.
    #[error(
        "batch {batch} would hold {runs} run(s) of {total}; each of the {batches} batches needs at least 2"
    )]
    TooFewRuns {
        /// Batch index.
        batch: usize,
        /// Runs that batch would hold.
        runs: usize,
        /// Total number of values.
        total: usize,
        /// Number of batches asked for.
        batches: usize,
    },
    /// Every value in a batch is identical and the runs carry no standard
    /// errors to floor its weight with (as many positions as terms, or runs
    /// that fit exactly): its inverse-variance weight would be infinite.
    #[error(
        "batch {batch} (runs {first}–{last}) has identical values and the runs give no standard \
         errors to bound its weight (they fit their positions exactly): add positions, so that \
         each run's own scatter is known"
    )]
    NoSpread {
        /// Batch index.
        batch: usize,
        /// First run of the batch.
        first: usize,
        /// Last run of the batch.
        last: usize,
    },
    /// A value is NaN or infinite.
    #[error("value {run} is not a finite number")]
    NonFinite {
        /// Index of the value (the run).
        run: usize,
    },
    /// The fused value or its standard error is not a finite number (values
    /// so extreme that the weighted mean overflows).
    #[error("the fused value or its standard error is not a representable number")]
    NotRepresentable,
}

/// Why an output could not be compensated into an input acceleration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CompensateError {
    /// The coefficients lack the scale factor `ki`.
    #[error("the coefficients have no scale factor `ki`, so the output cannot be inverted")]
    MissingScaleFactor,
    /// An input (output, `a_p` or `a_o`) is NaN or infinite.
    #[error("{0} is not a finite number")]
    NonFinite(&'static str),
    /// `∂U/∂a_i` is zero where the inversion needs it.
    #[error("∂U/∂a_i vanishes at a_i = {a_i}, so the output cannot be inverted there")]
    VanishingDerivative {
        /// The input acceleration at which the derivative vanished.
        a_i: f64,
    },
    /// Newton's iteration did not converge.
    #[error("Newton's iteration did not converge within {iterations} steps (last a_i = {a_i})")]
    NoConvergence {
        /// Steps taken.
        iterations: usize,
        /// The last iterate.
        a_i: f64,
    },
}

/// Formats a term list as `k0, kii, kpp`.
struct TermList<'a>(&'a [Term]);

impl fmt::Display for TermList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (n, t) in self.0.iter().enumerate() {
            if n > 0 {
                f.write_str(", ")?;
            }
            f.write_str(t.name())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_name_their_terms_in_words() {
        let e = Error::RankDeficient {
            terms: vec![Term::K0, Term::Kii, Term::Kpp],
            positions: 40,
            columns: 10,
            rank: 9,
        };
        assert_eq!(
            e.to_string(),
            "terms k0, kii, kpp cannot be separated by this tumble (40 positions, 10 terms, rank 9)"
        );
        let one = Error::RankDeficient {
            terms: vec![Term::Ko],
            positions: 8,
            columns: 3,
            rank: 2,
        };
        assert!(one.to_string().starts_with("terms ko cannot"), "{one}");
        let nested = Error::Fusion {
            term: Term::Kp,
            source: FusionError::NoSpread {
                batch: 1,
                first: 3,
                last: 5,
            },
        };
        assert_eq!(
            nested.to_string(),
            "coefficient `kp`: batch 1 (runs 3–5) has identical values and the runs give no \
             standard errors to bound its weight (they fit their positions exactly): add \
             positions, so that each run's own scatter is known"
        );
        assert_eq!(
            Error::CopiedRun { run: 4, copy_of: 1 }.to_string(),
            "run 4 is a copy of run 1: every reading holds the same samples, in the same number; \
             a repeated tumble never reads identically, so send each run's own data once"
        );
    }
}
