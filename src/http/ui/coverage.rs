//! How a document states the coverage of its expanded uncertainties: the
//! sentence that ends a method's description, for a stated coverage
//! probability, a fixed coverage factor, or (before either was stated per
//! coefficient) k and the normal probability.

use super::format::{factor, percent};

/// The coverage probability of a coverage factor `k` for a normal
/// distribution ([`accelcal_core::uncertainty::coverage_probability`]), as a
/// certificate states it ("coverage probability ≈ 95.4 %"): for results
/// computed before each coefficient stated its own.
pub fn probability(k: f64) -> String {
    let p = accelcal_core::uncertainty::coverage_probability(k) * 100.0;
    format!("coverage probability ≈ {p:.1} % (normal distribution)")
}

/// How the expanded uncertainties were formed, as the method's sentence
/// ends ("… combined in quadrature and expanded" + this): for a stated
/// probability, each coefficient's k from Student's t at its effective
/// degrees of freedom; for a fixed k, each one's probability from them;
/// for a result computed before either, k and the normal probability.
pub fn coverage_statement(u: &super::result::UncertaintyDoc) -> String {
    let per_term = u.terms.iter().all(|(_, b)| b.coverage_factor.is_some());
    stated(u.coverage_probability, u.coverage_factor, per_term)
}

/// [`coverage_statement`] of a document that states `probability` or
/// `factor`, for each coefficient (`per_term`) or, before that, once.
pub fn stated(stated_p: Option<f64>, fixed: Option<f64>, per_term: bool) -> String {
    let dof = "its effective degrees of freedom ν_eff (Welch–Satterthwaite, GUM G.2b, \
               truncated; the Type B components of the standards on the degrees of freedom \
               their certificates state, infinite otherwise)";
    match (stated_p, fixed, per_term) {
        (Some(p), _, true) => format!(
            " for a coverage probability of {}: each coefficient's coverage factor k is \
             Student's t for it at {dof}",
            percent(p)
        ),
        (None, Some(k), true) => format!(
            " with the coverage factor k = {} the sensor type fixes: each coefficient's \
             coverage probability p follows from Student's t at {dof}",
            factor(k)
        ),
        (_, k, _) => {
            let k = k.unwrap_or(2.0);
            format!(
                " with coverage factor k = {}, {}",
                factor(k),
                probability(k)
            )
        }
    }
}
