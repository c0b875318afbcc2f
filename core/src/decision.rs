//! Conformity decisions against a sensor type's limits (ILAC-G8:2019).
//!
//! For a fused value `x` with expanded uncertainty `U` and limits `min`,
//! `max` (either may be absent: unbounded on that side):
//!
//! * **simple acceptance**: pass when `min ≤ x ≤ max`, else fail;
//! * **guarded acceptance** (guard band `w = U`): pass when
//!   `min + U ≤ x ≤ max − U`; fail when `x < min − U` or `x > max + U`;
//!   otherwise conditional.
//!
//! The calibration's verdict is fail if any term fails, else conditional if
//! any is, else pass.

use serde::{Deserialize, Serialize};

use crate::term::{Term, TermMap};

/// How a value and its uncertainty are judged against limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Rule {
    /// The value alone against the limits.
    Simple,
    /// The value with its expanded uncertainty as guard band.
    Guarded,
}

/// A verdict, ordered from best to worst.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// Conforms.
    Pass,
    /// Within the limits but not by the guard band (guarded rule only).
    Conditional,
    /// Does not conform.
    Fail,
}

impl Verdict {
    /// The wire name.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Conditional => "conditional",
            Verdict::Fail => "fail",
        }
    }
}

/// The limits of one coefficient; an absent bound is no bound.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limit {
    /// Lower limit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min: Option<f64>,
    /// Upper limit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
}

/// The judgement of one coefficient.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TermDecision {
    /// The fused value judged.
    pub value: f64,
    /// The lower limit, if any.
    pub min: Option<f64>,
    /// The upper limit, if any.
    pub max: Option<f64>,
    /// Its expanded uncertainty.
    pub expanded: f64,
    /// The verdict.
    pub verdict: Verdict,
}

/// The judgement of a calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Decision {
    /// The rule applied.
    pub rule: Rule,
    /// The worst verdict of the terms.
    pub verdict: Verdict,
    /// Per limited term, in the limits' order.
    pub terms: TermMap<TermDecision>,
}

/// Judges one value.
pub fn judge(rule: Rule, value: f64, expanded: f64, limit: Limit) -> Verdict {
    let (lo, hi) = (
        limit.min.unwrap_or(f64::NEG_INFINITY),
        limit.max.unwrap_or(f64::INFINITY),
    );
    match rule {
        Rule::Simple if (lo..=hi).contains(&value) => Verdict::Pass,
        Rule::Simple => Verdict::Fail,
        Rule::Guarded if lo + expanded <= value && value <= hi - expanded => Verdict::Pass,
        Rule::Guarded if value < lo - expanded || value > hi + expanded => Verdict::Fail,
        Rule::Guarded => Verdict::Conditional,
    }
}

/// Judges every limited term; the terms named in `limits` must all be in
/// `values` and `expanded` (the caller refuses a model lacking one).
pub fn decide(
    rule: Rule,
    limits: &TermMap<Limit>,
    values: &TermMap<f64>,
    expanded: &TermMap<f64>,
) -> Result<Decision, Term> {
    let mut terms = Vec::with_capacity(limits.len());
    for (t, limit) in limits.iter() {
        let (Some(value), Some(u)) = (values.get(t), expanded.get(t)) else {
            return Err(t);
        };
        terms.push((
            t,
            TermDecision {
                value: *value,
                min: limit.min,
                max: limit.max,
                expanded: *u,
                verdict: judge(rule, *value, *u, *limit),
            },
        ));
    }
    let verdict = terms
        .iter()
        .map(|(_, d)| d.verdict)
        .max()
        .unwrap_or(Verdict::Pass);
    Ok(Decision {
        rule,
        verdict,
        terms: TermMap(terms),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limit(min: f64, max: f64) -> Limit {
        Limit {
            min: Some(min),
            max: Some(max),
        }
    }

    #[test]
    fn simple_acceptance_is_the_value_against_the_limits() {
        let l = limit(-1.0, 1.0);
        for (x, v) in [
            (-1.0, Verdict::Pass),
            (1.0, Verdict::Pass),
            (0.0, Verdict::Pass),
            (1.0001, Verdict::Fail),
            (-1.5, Verdict::Fail),
        ] {
            assert_eq!(judge(Rule::Simple, x, 0.5, l), v, "{x}");
        }
        assert_eq!(
            judge(
                Rule::Simple,
                1e9,
                0.5,
                Limit {
                    min: Some(0.0),
                    max: None
                }
            ),
            Verdict::Pass
        );
    }

    /// ILAC-G8 with guard band U = 0.25 on limits ±1: pass inside ±0.75,
    /// fail outside ±1.25, conditional between; the band edges belong to
    /// the better verdict.
    #[test]
    fn guarded_acceptance_has_three_zones() {
        let l = limit(-1.0, 1.0);
        for (x, v) in [
            (0.0, Verdict::Pass),
            (0.75, Verdict::Pass),
            (-0.75, Verdict::Pass),
            (0.76, Verdict::Conditional),
            (1.0, Verdict::Conditional),
            (1.25, Verdict::Conditional),
            (-1.25, Verdict::Conditional),
            (1.2501, Verdict::Fail),
            (-1.3, Verdict::Fail),
        ] {
            assert_eq!(judge(Rule::Guarded, x, 0.25, l), v, "{x}");
        }
        let upper_only = Limit {
            min: None,
            max: Some(1.0),
        };
        assert_eq!(judge(Rule::Guarded, -1e6, 0.25, upper_only), Verdict::Pass);
        assert_eq!(
            judge(Rule::Guarded, 0.9, 0.25, upper_only),
            Verdict::Conditional
        );
    }

    #[test]
    fn the_verdict_is_the_worst_term() {
        let limits = TermMap(vec![
            (Term::K0, limit(-1.0, 1.0)),
            (Term::Ki, limit(1.0, 2.0)),
        ]);
        let u = TermMap(vec![(Term::K0, 0.1), (Term::Ki, 0.1)]);
        let d = |k0: f64, ki: f64| {
            decide(
                Rule::Guarded,
                &limits,
                &TermMap(vec![(Term::K0, k0), (Term::Ki, ki)]),
                &u,
            )
            .unwrap()
        };
        assert_eq!(d(0.0, 1.5).verdict, Verdict::Pass);
        assert_eq!(d(0.95, 1.5).verdict, Verdict::Conditional);
        assert_eq!(d(0.95, 2.5).verdict, Verdict::Fail);
        assert_eq!(
            d(0.95, 2.5).terms.get(Term::K0).unwrap().verdict,
            Verdict::Conditional
        );
        let missing = decide(Rule::Simple, &limits, &TermMap(vec![(Term::K0, 0.0)]), &u);
        assert_eq!(missing, Err(Term::Ki));
    }
}
