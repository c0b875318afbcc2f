//! Across-run estimates of every coefficient: the mean and the fused value,
//! each with its eq. 8 dispersion, assembled term by term from
//! [`crate::fusion`]. This is also "fusion of given values": callers may pass
//! per-run coefficients they identified elsewhere (the paper's Table 2).

use serde::Serialize;

use crate::fusion::{self, Dispersion};
use crate::term::TermMap;
use crate::{Error, Term};

/// The arithmetic mean of each coefficient (eq. 1) and eq. 8 about it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeanEstimate {
    /// `x̄` per term.
    pub coefficients: TermMap<f64>,
    /// Eq. 8 about the mean, absolute; `None` for a single run.
    pub dispersion: Option<TermMap<f64>>,
    /// Eq. 8 about the mean divided by `|x̄|` (`null` when `x̄ = 0`); `None`
    /// for a single run.
    pub relative_dispersion: Option<TermMap<Option<f64>>>,
}

/// One batch, shared by every term: its runs and per-term mean and deviation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BatchSummary {
    /// Run indices (0-based) in the batch.
    pub runs: Vec<usize>,
    /// Batch mean `x̄_p` per term.
    pub mean: TermMap<f64>,
    /// Batch sample standard deviation `s_p` per term.
    pub std: TermMap<f64>,
}

/// The batch-estimation fusion of each coefficient and eq. 8 about it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FusedEstimate {
    /// The batches.
    pub batches: Vec<BatchSummary>,
    /// Fused value `x⁺` per term.
    pub coefficients: TermMap<f64>,
    /// Fused standard error `1/sqrt(Σ w_p)` per term.
    pub std_errors: TermMap<f64>,
    /// The degrees of freedom of each standard error
    /// ([`crate::coverage`]): from the batches and their weights, or a
    /// single run's residual degrees of freedom. Stated in each term's
    /// uncertainty budget rather than here.
    #[serde(skip)]
    pub dof: TermMap<f64>,
    /// Eq. 8 about the fused value, absolute; `None` for a single run.
    pub dispersion: Option<TermMap<f64>>,
    /// Eq. 8 about the fused value divided by `|x⁺|` (`null` when `x⁺ = 0`);
    /// `None` for a single run.
    pub relative_dispersion: Option<TermMap<Option<f64>>>,
    /// Why there are no batches and no eq. 8 ([`SINGLE_RUN`]), when so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<&'static str>,
}

/// What a single run's estimates say of themselves.
pub const SINGLE_RUN: &str = "a single run: the fused and mean coefficients are the run's own, \
    with its own standard errors; batches and eq. 8 need two runs or more";

/// Both across-run estimates.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Estimates {
    /// The traditional estimate (eq. 1).
    pub mean: MeanEstimate,
    /// The paper's batch-estimation fusion (eq. 4–7, general variance).
    pub fused: FusedEstimate,
}

/// Mean and fused estimates of per-run values, keyed by term, over `batches`
/// batches. Every term must have the same number of values (one per run).
pub fn estimate(values: &TermMap<Vec<f64>>, batches: usize) -> Result<Estimates, Error> {
    estimate_with_floors(values, batches, &TermMap(Vec::new()))
}

/// As [`estimate`], each term's batches weighted with their deviation floored
/// at that term's entry of `floors` (see [`fusion::consistency_floor`]; a term
/// without an entry has none).
pub fn estimate_with_floors(
    values: &TermMap<Vec<f64>>,
    batches: usize,
    floors: &TermMap<f64>,
) -> Result<Estimates, Error> {
    let Some((_, first)) = values.0.first() else {
        return Err(Error::NoValues);
    };
    let runs = first.len();
    for (term, xs) in values.iter() {
        if xs.len() != runs {
            return Err(Error::ValueCount {
                term,
                expected: runs,
                found: xs.len(),
            });
        }
    }
    let mut fusions = Vec::with_capacity(values.len());
    for (term, xs) in values.iter() {
        let floor = floors.get(term).copied().unwrap_or(0.0);
        let f = fusion::fuse_with_floor(xs, batches, floor)
            .map_err(|source| Error::Fusion { term, source })?;
        fusions.push((term, xs.as_slice(), f));
    }

    let per_term = |g: &dyn Fn(&[f64], &fusion::Fusion) -> f64| -> TermMap<f64> {
        TermMap(fusions.iter().map(|(t, xs, f)| (*t, g(xs, f))).collect())
    };
    let about = |k: &dyn Fn(&[f64], &fusion::Fusion) -> f64| -> Vec<(Term, Dispersion)> {
        fusions
            .iter()
            .map(|(t, xs, f)| {
                let d = fusion::dispersion(xs, k(xs, f)).expect("fusion needs two runs or more");
                (*t, d)
            })
            .collect()
    };
    let split = |ds: Vec<(Term, Dispersion)>| {
        (
            TermMap(ds.iter().map(|(t, d)| (*t, d.absolute)).collect()),
            TermMap(ds.iter().map(|(t, d)| (*t, d.relative)).collect()),
        )
    };

    let (mean_abs, mean_rel) = split(about(&|xs, _| fusion::mean(xs)));
    let (fused_abs, fused_rel) = split(about(&|_, f| f.value));
    let batch_summaries = (0..batches)
        .map(|p| BatchSummary {
            runs: fusions[0].2.batches[p].runs.clone().collect(),
            mean: per_term(&|_, f| f.batches[p].mean),
            std: per_term(&|_, f| f.batches[p].std),
        })
        .collect();

    let estimates = Estimates {
        mean: MeanEstimate {
            coefficients: per_term(&|xs, _| fusion::mean(xs)),
            dispersion: Some(mean_abs),
            relative_dispersion: Some(mean_rel),
        },
        fused: FusedEstimate {
            batches: batch_summaries,
            coefficients: per_term(&|_, f| f.value),
            std_errors: per_term(&|_, f| f.std_error),
            dof: per_term(&|_, f| f.dof),
            dispersion: Some(fused_abs),
            relative_dispersion: Some(fused_rel),
            note: None,
        },
    };
    finite(&estimates.mean.coefficients, "mean")?;
    if let Some(d) = &estimates.mean.dispersion {
        finite(d, "dispersion about the mean")?;
    }
    finite(&estimates.fused.coefficients, "fused value")?;
    finite(&estimates.fused.std_errors, "fused standard error")?;
    if let Some(d) = &estimates.fused.dispersion {
        finite(d, "dispersion about the fused value")?;
    }
    Ok(estimates)
}

/// The estimates of a single run: its coefficients and its own standard
/// errors on its `dof` residual degrees of freedom, no batches and no eq. 8
/// ([`SINGLE_RUN`]).
pub fn single_run(coefficients: &TermMap<f64>, std_errors: &TermMap<f64>, dof: usize) -> Estimates {
    Estimates {
        mean: MeanEstimate {
            coefficients: coefficients.clone(),
            dispersion: None,
            relative_dispersion: None,
        },
        fused: FusedEstimate {
            batches: Vec::new(),
            coefficients: coefficients.clone(),
            std_errors: std_errors.clone(),
            dof: TermMap(std_errors.iter().map(|(t, _)| (t, dof as f64)).collect()),
            dispersion: None,
            relative_dispersion: None,
            note: Some(SINGLE_RUN),
        },
    }
}

/// Refuses a map holding a non-finite number, naming the term and quantity:
/// nothing accelcal stores or serves may be NaN or infinite.
pub(crate) fn finite(values: &TermMap<f64>, quantity: &'static str) -> Result<(), Error> {
    match values.iter().find(|(_, v)| !v.is_finite()) {
        Some((term, _)) => Err(Error::NonFiniteResult { term, quantity }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FusionError;

    #[test]
    fn unequal_value_counts_are_refused() {
        let v = TermMap(vec![
            (Term::K0, vec![1.0, 2.0, 3.0, 4.0]),
            (Term::Ki, vec![1.0, 2.0, 3.0]),
        ]);
        assert_eq!(
            estimate(&v, 1),
            Err(Error::ValueCount {
                term: Term::Ki,
                expected: 4,
                found: 3
            })
        );
    }

    #[test]
    fn fusion_errors_name_the_term() {
        let v = TermMap(vec![
            (Term::K0, vec![1.0, 2.0, 3.0, 4.0]),
            (Term::Kp, vec![1.0, 1.0, 3.0, 4.0]),
        ]);
        assert_eq!(
            estimate(&v, 2),
            Err(Error::Fusion {
                term: Term::Kp,
                source: FusionError::NoSpread {
                    batch: 0,
                    first: 0,
                    last: 1
                }
            })
        );
    }

    #[test]
    fn non_finite_quantities_are_refused_with_their_term() {
        let ok = TermMap(vec![(Term::K0, 1.0), (Term::Ki, 2.0)]);
        assert_eq!(finite(&ok, "mean"), Ok(()));
        let bad = TermMap(vec![(Term::K0, 1.0), (Term::Ki, f64::INFINITY)]);
        assert_eq!(
            finite(&bad, "mean"),
            Err(Error::NonFiniteResult {
                term: Term::Ki,
                quantity: "mean"
            })
        );
    }

    #[test]
    fn each_term_is_floored_by_its_own_entry() {
        let xs = vec![1.0, 1.000_002, 3.0, 5.0];
        let v = TermMap(vec![(Term::K0, xs.clone()), (Term::Ki, xs.clone())]);
        let floors = TermMap(vec![(Term::Ki, 2f64.sqrt())]);
        let e = estimate_with_floors(&v, 2, &floors).unwrap();
        let plain = fusion::fuse(&xs, 2).unwrap().value;
        let floored = fusion::fuse_with_floor(&xs, 2, 2f64.sqrt()).unwrap().value;
        assert_eq!(e.fused.coefficients.get(Term::K0), Some(&plain));
        assert_eq!(e.fused.coefficients.get(Term::Ki), Some(&floored));
        assert_ne!(plain, floored);
    }

    #[test]
    fn fused_dispersion_is_never_below_the_mean_dispersion() {
        let v = TermMap(vec![(Term::K0, vec![1.0, 1.5, 1.1, 4.0, 5.0, 4.2])]);
        let e = estimate(&v, 2).unwrap();
        let (m, f) = (
            e.mean.dispersion.as_ref().unwrap()[Term::K0],
            e.fused.dispersion.as_ref().unwrap()[Term::K0],
        );
        assert!(f > m, "{f} vs {m}");
        assert_eq!(e.fused.batches[1].runs, vec![3, 4, 5]);
    }
}
