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

    /// The polynomial degree of the regressor in the specific force: 0 for
    /// `k0`; 1 for `ki`, `kp`, `ko`; 2 for the cross terms and squares; 3 for
    /// `kiii`. A regressor of degree `n` scales by `cⁿ` when `a` scales by `c`.
    pub const fn degree(self) -> u32 {
        match self {
            Term::K0 => 0,
            Term::Ki | Term::Kp | Term::Ko => 1,
            Term::Kio | Term::Kop | Term::Kpi | Term::Kii | Term::Kpp | Term::Koo => 2,
            Term::Kiii => 3,
        }
    }

    /// The gradient `(∂/∂a_i, ∂/∂a_p, ∂/∂a_o)` of the regressor at `a`.
    pub fn gradient(self, a: &Gravity) -> [f64; 3] {
        let Gravity { i, p, o } = *a;
        match self {
            Term::K0 => [0.0, 0.0, 0.0],
            Term::Ki => [1.0, 0.0, 0.0],
            Term::Kp => [0.0, 1.0, 0.0],
            Term::Ko => [0.0, 0.0, 1.0],
            Term::Kio => [o, 0.0, i],
            Term::Kop => [0.0, o, p],
            Term::Kpi => [p, i, 0.0],
            Term::Kii => [2.0 * i, 0.0, 0.0],
            Term::Kpp => [0.0, 2.0 * p, 0.0],
            Term::Koo => [0.0, 0.0, 2.0 * o],
            Term::Kiii => [3.0 * i * i, 0.0, 0.0],
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

impl<T> std::ops::Index<Term> for TermMap<T> {
    type Output = T;

    /// The value for `term`.
    ///
    /// # Panics
    /// When the map has no value for `term` (as `HashMap`'s index does);
    /// [`TermMap::get`] is the fallible form.
    fn index(&self, term: Term) -> &T {
        match self.get(term) {
            Some(v) => v,
            None => panic!("no value for term `{term}`"),
        }
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
    fn names_display_and_serialise() {
        assert_eq!(Term::Kpi.to_string(), "kpi");
        assert_eq!(format!("{}", Term::K0), "k0");
        assert_eq!(serde_json::to_string(&Term::Kiii).unwrap(), "\"kiii\"");
        assert_eq!(serde_json::from_str::<Term>("\"koo\"").unwrap(), Term::Koo);
    }

    #[test]
    fn models_answer_for_their_terms() {
        let m = Model::new(vec![Term::K0, Term::Kp, Term::Kiii]).unwrap();
        assert_eq!((m.len(), m.is_empty()), (3, false));
        assert_eq!(m.index_of(Term::Kp), Some(1));
        assert_eq!(m.index_of(Term::Kiii), Some(2));
        assert_eq!(m.index_of(Term::Ki), None);
        let parsed: Model = serde_json::from_str(r#"["k0", "kp", "kiii"]"#).unwrap();
        assert_eq!(parsed, m);
        assert!(serde_json::from_str::<Model>("[]").is_err());
        assert!(serde_json::from_str::<Model>(r#"["k0", "k0"]"#).is_err());
        assert_eq!(serde_json::to_string(&m).unwrap(), r#"["k0","kp","kiii"]"#);
    }

    #[test]
    fn term_maps_read_and_write_objects_in_order() {
        let map: TermMap<f64> = serde_json::from_str(r#"{"kp": 2.5, "k0": 1.0}"#).unwrap();
        assert_eq!((map.len(), map.is_empty()), (2, false));
        assert_eq!(map.get(Term::Kp), Some(&2.5));
        assert_eq!(map.get(Term::Ki), None);
        assert_eq!(
            serde_json::to_string(&map).unwrap(),
            r#"{"kp":2.5,"k0":1.0}"#
        );
        assert!(TermMap::<f64>(vec![]).is_empty());
        let dup = serde_json::from_str::<TermMap<f64>>(r#"{"k0": 1, "k0": 2}"#).unwrap_err();
        assert!(dup.to_string().contains("duplicate term `k0`"), "{dup}");
        let wrong = serde_json::from_str::<TermMap<f64>>("[1]").unwrap_err();
        assert!(
            wrong.to_string().contains("an object keyed by term name"),
            "{wrong}"
        );
    }

    /// Degrees and gradients against the regressors themselves: Euler's
    /// relation `∇f·a = degree·f` for homogeneous polynomials, and central
    /// differences.
    #[test]
    fn degrees_and_gradients_agree_with_the_regressors() {
        let a = Gravity {
            i: 0.3,
            p: -0.7,
            o: 0.2,
        };
        for t in Term::ALL {
            let g = t.gradient(&a);
            let euler = g[0] * a.i + g[1] * a.p + g[2] * a.o;
            assert!(
                (euler - f64::from(t.degree()) * t.regressor(&a)).abs() < 1e-15,
                "{t}"
            );
            for axis in 0..3 {
                let h = 1e-6;
                let mut up = a.to_array();
                let mut down = a.to_array();
                up[axis] += h;
                down[axis] -= h;
                let numeric = (t.regressor(&Gravity::from(up)) - t.regressor(&Gravity::from(down)))
                    / (2.0 * h);
                assert!((numeric - g[axis]).abs() < 1e-9, "{t} axis {axis}");
            }
        }
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
