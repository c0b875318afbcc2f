//! A temperature model judged against a sensor type's limits (issue 45
//! item 4): every limited coefficient at every set point — its fused value
//! with `U = k · se`, `k` for the set point's fused degrees of freedom — and
//! across the valid range — `c(T)` with `U = k · √(vᵀ C v)`, `k` for the
//! polynomial's `ν = N − D − 1` when the scatter set its covariance (the
//! Birge ratio inflated it), for infinite degrees of freedom otherwise, and
//! the thermometer's `u_T · |c′(T)|` in `u` when one was named
//! ([`ThermalModel::read`]) —
//! each judged by the type's rule ([`accelcal_core::decision::judge`]).
//! The range is judged at the ends, where `c′(T) = 0`, and at
//! [`SCAN`] evenly spaced temperatures between (where `U` grows while `c`
//! does not move, the worst need not be an extreme of `c`). A coefficient's
//! verdict is its worst, stated with where; the model's, the worst of its
//! coefficients'.

use accelcal_core::coverage::Coverage;
use accelcal_core::decision::{Limit, Rule, Verdict, judge};
use accelcal_core::thermal::Polynomial;
use accelcal_core::{Term, TermMap};
use serde::{Deserialize, Serialize};

use super::ThermalModel;
use super::at::stationary;

mod triad;
pub use triad::{TriadThermalDecision, axis_model, decide_triad_model};

/// Temperatures scanned across the range, ends included.
pub const SCAN: usize = 401;

/// One judgement at one temperature.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Judged {
    /// Where, °C.
    pub temperature_c: f64,
    /// The value judged.
    pub value: f64,
    /// Its expanded uncertainty.
    pub expanded: f64,
    /// `k`.
    pub coverage_factor: f64,
    /// The verdict.
    pub verdict: Verdict,
}

/// One coefficient judged over temperature.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThermalTermDecision {
    /// The lower limit, if any.
    pub min: Option<f64>,
    /// The upper limit, if any.
    pub max: Option<f64>,
    /// At each set point, coolest first.
    pub set_points: Vec<Judged>,
    /// The worst across the range.
    pub range: Judged,
    /// The worst of all: its verdict is the coefficient's.
    pub worst: Judged,
}

/// A temperature model judged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThermalDecision {
    /// The rule applied.
    pub rule: Rule,
    /// The worst verdict of the coefficients.
    pub verdict: Verdict,
    /// Per limited coefficient, in the limits' order.
    pub terms: TermMap<ThermalTermDecision>,
}

/// Which judgement is worse: the worse verdict, then the one nearer (or
/// farther past) a limit.
fn worse(a: Judged, b: Judged, limit: Limit) -> Judged {
    // How far the guard band reaches past the nearest limit (positive: past).
    let reach = |j: &Judged| {
        let hi = limit
            .max
            .map_or(f64::NEG_INFINITY, |m| j.value + j.expanded - m);
        let lo = limit
            .min
            .map_or(f64::NEG_INFINITY, |m| m - (j.value - j.expanded));
        hi.max(lo)
    };
    match a.verdict.cmp(&b.verdict) {
        std::cmp::Ordering::Greater => a,
        std::cmp::Ordering::Less => b,
        std::cmp::Ordering::Equal if reach(&b) > reach(&a) => b,
        std::cmp::Ordering::Equal => a,
    }
}

/// `k` for `dof` degrees of freedom (`None`: infinite).
fn factor(coverage: Coverage, dof: Option<u64>) -> f64 {
    coverage.at(dof).factor
}

/// Where `c` is judged on its range: the scan and `c′(T) = 0`.
fn temperatures(p: &Polynomial) -> Vec<f64> {
    let [lo, hi] = p.range_c;
    let mut ts: Vec<f64> = (0..SCAN)
        .map(|i| lo + (hi - lo) * i as f64 / (SCAN - 1) as f64)
        .collect();
    ts.extend(stationary(p));
    ts
}

/// `model` judged by `rule` against `limits` with `coverage`; the term a
/// limit names that the model lacks is the error.
pub fn decide_model(
    model: &ThermalModel,
    rule: Rule,
    limits: &TermMap<Limit>,
    coverage: Coverage,
) -> Result<ThermalDecision, Term> {
    let mut terms = Vec::with_capacity(limits.len());
    for (term, limit) in limits.iter() {
        let Some(p) = model.coefficients.get(term) else {
            return Err(term);
        };
        let at = |temperature_c: f64, value: f64, u: f64, k: f64| Judged {
            temperature_c,
            value,
            expanded: k * u,
            coverage_factor: k,
            verdict: judge(rule, value, k * u, *limit),
        };
        let set_points: Vec<Judged> = model
            .set_points
            .iter()
            .map(|s| {
                let value = s.coefficients.get(term).copied().unwrap_or(f64::NAN);
                let u = s.std_errors.get(term).copied().unwrap_or(f64::NAN);
                let dof = s
                    .dof
                    .as_ref()
                    .and_then(|d| d.get(term))
                    .filter(|d| d.is_finite())
                    .map(|d| *d as u64);
                at(s.temperature_c, value, u, factor(coverage, dof))
            })
            .collect();
        let k = factor(coverage, (p.inflation > 1.0).then_some(p.dof as u64));
        let range = temperatures(p)
            .into_iter()
            .map(|t| {
                let (value, u) = model.read(p, t);
                at(t, value, u, k)
            })
            .reduce(|a, b| worse(a, b, *limit))
            .expect("the range's ends");
        let worst = set_points
            .iter()
            .copied()
            .fold(range, |a, b| worse(a, b, *limit));
        terms.push((
            term,
            ThermalTermDecision {
                min: limit.min,
                max: limit.max,
                set_points,
                range,
                worst,
            },
        ));
    }
    let verdict = terms
        .iter()
        .map(|(_, d)| d.worst.verdict)
        .max()
        .unwrap_or(Verdict::Pass);
    Ok(ThermalDecision {
        rule,
        verdict,
        terms: TermMap(terms),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use accelcal_core::thermal::Polynomial;

    /// `k0(T) = 1e-3 (T − 20)` on 0…40 °C, judged against `k0 ≤ 0.05`
    /// with `k = 2`: the worst of the range is at 40 °C, its `U` is
    /// `2 √(vᵀ C v + (u_T · 1e-3)²)` computed here by hand.
    #[test]
    fn the_range_is_judged_with_the_thermometers_term() {
        let p = Polynomial {
            reference_c: 20.0,
            degree: 1,
            coefficients: vec![0.0, 1e-3],
            std_uncertainties: vec![1e-5, 1e-7],
            covariance: vec![vec![1e-10, 0.0], vec![0.0, 1e-14]],
            chi2: 1.0,
            dof: 3,
            inflation: 1.0,
            range_c: [0.0, 40.0],
            selection: Vec::new(),
        };
        let mut model = ThermalModel {
            sensor_id: "S".into(),
            unit: "V".into(),
            tolerance_k: 0.5,
            selection: "fixed".into(),
            fitted_with: Default::default(),
            set_points: Vec::new(),
            coefficients: TermMap(vec![(Term::K0, p)]),
            thermometer_std_c: None,
        };
        let limits = TermMap(vec![(
            Term::K0,
            Limit {
                min: None,
                max: Some(0.05),
            },
        )]);
        let judged = |m: &ThermalModel| {
            decide_model(m, Rule::Simple, &limits, Coverage::Factor(2.0)).unwrap()
        };
        let u_fit = (1e-10f64 + 20.0 * 20.0 * 1e-14).sqrt();
        let plain = judged(&model).terms.get(Term::K0).unwrap().range;
        assert_eq!(plain.temperature_c, 40.0);
        assert!((plain.expanded - 2.0 * u_fit).abs() < 1e-18);
        model.thermometer_std_c = Some(0.5);
        let with = judged(&model).terms.get(Term::K0).unwrap().range;
        let want = 2.0 * (u_fit * u_fit + (0.5 * 1e-3f64).powi(2)).sqrt();
        assert_eq!(with.temperature_c, 40.0);
        assert!(
            (with.expanded - want).abs() < 1e-15,
            "{} {want}",
            with.expanded
        );
        assert_eq!((with.value, with.verdict), (0.02, Verdict::Pass));
    }
}
