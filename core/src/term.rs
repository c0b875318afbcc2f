//! Terms of the static accelerometer model and the ordered model they form.
//!
//! The static model of a pendulous accelerometer (paper eq. 2, plus the
//! third-order term of IEEE Std 1293) is
//!
//! ```text
//! U = k0 + ki·a_i + kp·a_p + ko·a_o + kio·a_i·a_o + kop·a_o·a_p + kpi·a_p·a_i
//!        + kii·a_i² + kpp·a_p² + koo·a_o² + kiii·a_i³
//! ```
//!
//! with `a_i, a_p, a_o` the specific-force components in g along the input,
//! pendulous and output axes. Each [`Term`] is one coefficient of that sum and
//! knows its regressor (its column of the design matrix). A [`Model`] is an
//! ordered, non-empty list of distinct terms; the paper's pendulum model
//! (eq. 3) is `[k0, ki, kp]`.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::Error;
use crate::position::Gravity;

/// One coefficient of the static model, named as in the paper and IEEE 1293.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Term {
    /// Bias: regressor `1`.
    K0,
    /// Scale factor K1: regressor `a_i`.
    Ki,
    /// Pendulous-axis sensitivity (the paper's misalignment α): regressor `a_p`.
    Kp,
    /// Output-axis sensitivity: regressor `a_o`.
    Ko,
    /// Cross-coupling input–output: regressor `a_i·a_o`.
    Kio,
    /// Cross-coupling output–pendulous: regressor `a_o·a_p`.
    Kop,
    /// Cross-coupling pendulous–input: regressor `a_p·a_i`.
    Kpi,
    /// Second-order non-linearity K2: regressor `a_i²`.
    Kii,
    /// Pendulous-axis square: regressor `a_p²`.
    Kpp,
    /// Output-axis square: regressor `a_o²`.
    Koo,
    /// Third-order non-linearity K3 (IEEE 1293): regressor `a_i³`.
    Kiii,
}

impl Term {
    /// Every term, in the canonical order of eq. 2 followed by `kiii`.
    pub const ALL: [Term; 11] = [
        Term::K0,
        Term::Ki,
        Term::Kp,
        Term::Ko,
        Term::Kio,
        Term::Kop,
        Term::Kpi,
        Term::Kii,
        Term::Kpp,
        Term::Koo,
        Term::Kiii,
    ];

    /// The term's name as used on the wire (`"k0"`, `"ki"`, …).
    pub const fn name(self) -> &'static str {
        match self {
            Term::K0 => "k0",
            Term::Ki => "ki",
            Term::Kp => "kp",
            Term::Ko => "ko",
            Term::Kio => "kio",
            Term::Kop => "kop",
            Term::Kpi => "kpi",
            Term::Kii => "kii",
            Term::Kpp => "kpp",
            Term::Koo => "koo",
            Term::Kiii => "kiii",
        }
    }

    /// The regressor of this term at specific force `a` (one entry of a design row).
    pub fn regressor(self, a: &Gravity) -> f64 {
        let Gravity { i, p, o } = *a;
        match self {
            Term::K0 => 1.0,
            Term::Ki => i,
            Term::Kp => p,
            Term::Ko => o,
            Term::Kio => i * o,
            Term::Kop => o * p,
            Term::Kpi => p * i,
            Term::Kii => i * i,
            Term::Kpp => p * p,
            Term::Koo => o * o,
            Term::Kiii => i * i * i,
        }
    }
}

impl fmt::Display for Term {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The error of parsing an unknown term name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown term `{0}`; expected one of k0, ki, kp, ko, kio, kop, kpi, kii, kpp, koo, kiii")]
pub struct UnknownTerm(pub String);

impl FromStr for Term {
    type Err = UnknownTerm;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Term::ALL
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| UnknownTerm(s.to_owned()))
    }
}

impl Serialize for Term {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for Term {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = <std::borrow::Cow<'de, str>>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// An ordered, non-empty list of distinct terms: the columns of the design.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Model(Vec<Term>);

impl Model {
    /// Builds a model, refusing an empty list or a repeated term.
    pub fn new(terms: Vec<Term>) -> Result<Self, Error> {
        if terms.is_empty() {
            return Err(Error::EmptyModel);
        }
        for (index, term) in terms.iter().enumerate() {
            if terms[..index].contains(term) {
                return Err(Error::DuplicateTerm { index, term: *term });
            }
        }
        Ok(Model(terms))
    }

    /// The paper's simplified pendulum model (eq. 3): `[k0, ki, kp]`.
    pub fn pendulum() -> Self {
        Model(vec![Term::K0, Term::Ki, Term::Kp])
    }

    /// The terms, in column order.
    pub fn terms(&self) -> &[Term] {
        &self.0
    }

    /// Number of terms (columns).
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Always false: a model has at least one term.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Column index of `term`, if the model has it.
    pub fn index_of(&self, term: Term) -> Option<usize> {
        self.0.iter().position(|t| *t == term)
    }
}

impl Default for Model {
    fn default() -> Self {
        Model::pendulum()
    }
}

impl Serialize for Model {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

impl<'de> Deserialize<'de> for Model {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let terms = Vec::<Term>::deserialize(d)?;
        Model::new(terms).map_err(serde::de::Error::custom)
    }
}

/// Values keyed by term, kept in model order; serialised as a JSON object
/// `{"k0": …, "ki": …}`.
#[derive(Clone, Debug, PartialEq)]
pub struct TermMap<T>(pub Vec<(Term, T)>);

impl<T> TermMap<T> {
    /// The value for `term`, if present.
    pub fn get(&self, term: Term) -> Option<&T> {
        self.0.iter().find(|(t, _)| *t == term).map(|(_, v)| v)
    }

    /// Iterates over `(term, value)` pairs in order.
    pub fn iter(&self) -> impl Iterator<Item = (Term, &T)> {
        self.0.iter().map(|(t, v)| (*t, v))
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether the map has no entries.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl<T: Serialize> Serialize for TermMap<T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_map(self.0.iter().map(|(t, v)| (t.name(), v)))
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for TermMap<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> serde::de::Visitor<'de> for Visitor<T> {
            type Value = TermMap<T>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("an object keyed by term name")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<Self::Value, A::Error> {
                let mut out: Vec<(Term, T)> = Vec::new();
                while let Some(term) = map.next_key::<Term>()? {
                    if out.iter().any(|(t, _)| *t == term) {
                        return Err(serde::de::Error::custom(format!("duplicate term `{term}`")));
                    }
                    out.push((term, map.next_value()?));
                }
                Ok(TermMap(out))
            }
        }
        d.deserialize_map(Visitor(std::marker::PhantomData))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for t in Term::ALL {
            assert_eq!(t.name().parse::<Term>(), Ok(t));
        }
        assert_eq!(
            "K0".parse::<Term>(),
            Err(UnknownTerm("K0".into())),
            "names are case-sensitive"
        );
    }

    #[test]
    fn regressors_follow_eq_2() {
        let a = Gravity {
            i: 2.0,
            p: 3.0,
            o: 5.0,
        };
        let got: Vec<f64> = Term::ALL.iter().map(|t| t.regressor(&a)).collect();
        assert_eq!(
            got,
            [1.0, 2.0, 3.0, 5.0, 10.0, 15.0, 6.0, 4.0, 9.0, 25.0, 8.0]
        );
    }

    #[test]
    fn model_refuses_empty_and_duplicates() {
        assert_eq!(Model::new(vec![]), Err(Error::EmptyModel));
        assert_eq!(
            Model::new(vec![Term::K0, Term::Ki, Term::K0]),
            Err(Error::DuplicateTerm {
                index: 2,
                term: Term::K0
            })
        );
        assert_eq!(Model::default().terms(), &[Term::K0, Term::Ki, Term::Kp]);
    }
}
