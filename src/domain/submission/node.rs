//! A small framework for reading JSON with serde without building a generic
//! tree: each part of a document is read by a [`Node`] that receives either a
//! [`Scalar`] or the sequence/map access itself, so values of the wrong kind
//! are recorded as field errors (and skipped) instead of aborting the parse.
//! Only a syntax error aborts.

use std::fmt;

use serde::de::{self, DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};

use crate::domain::field::{Errors, Loc};
use crate::domain::text::{Chars, check_str, echo};

/// A JSON value other than an array or object, or only the kind of one.
#[derive(Debug, Clone, PartialEq)]
pub enum Scalar {
    /// `null`.
    Null,
    /// `true` or `false`.
    Bool,
    /// A number, and the value as an unsigned integer when it was written as one.
    Num(f64, Option<u64>),
    /// A string.
    Str(String),
    /// An array (its contents skipped).
    Array,
    /// An object (its contents skipped).
    Object,
}

impl Scalar {
    /// The JSON kind, for messages ("must be a number, not a string").
    pub fn kind(&self) -> &'static str {
        match self {
            Scalar::Null => "null",
            Scalar::Bool => "a boolean",
            Scalar::Num(..) => "a number",
            Scalar::Str(_) => "a string",
            Scalar::Array => "an array",
            Scalar::Object => "an object",
        }
    }

    /// A string of 1 to `max` characters of the class.
    pub fn string(self, max: usize, chars: Chars) -> Result<String, String> {
        match self {
            Scalar::Str(s) => check_str(&s, max, chars).map(|()| s),
            other => Err(format!("must be a string, not {}", other.kind())),
        }
    }

    /// A finite number of magnitude at most `bound`.
    pub fn number(&self, bound: f64) -> Result<f64, String> {
        match self {
            Scalar::Num(x, _) if x.is_finite() && x.abs() <= bound => Ok(*x),
            Scalar::Num(..) => Err(format!(
                "must be a finite number of magnitude at most {bound:e}"
            )),
            other => Err(format!("must be a number, not {}", other.kind())),
        }
    }

    /// An integer in `min..=max`.
    pub fn integer(&self, min: u64, max: u64) -> Result<u64, String> {
        match self {
            Scalar::Num(_, Some(n)) if (min..=max).contains(n) => Ok(*n),
            Scalar::Num(..) => Err(format!("must be an integer from {min} to {max}")),
            other => Err(format!("must be an integer, not {}", other.kind())),
        }
    }
}

/// Reads one JSON value.
pub trait Node<'de>: Sized {
    /// What reading it gives.
    type Out;

    /// A value that is not an array or object (or one this node skipped).
    fn scalar(self, value: Scalar) -> Self::Out;

    /// An array; by default skipped and handled as [`Scalar::Array`].
    fn seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Out, A::Error> {
        while seq.next_element::<IgnoredAny>()?.is_some() {}
        Ok(self.scalar(Scalar::Array))
    }

    /// An object; by default skipped and handled as [`Scalar::Object`].
    fn map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Out, A::Error> {
        while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
        Ok(self.scalar(Scalar::Object))
    }
}

/// Reads a value with a [`Node`]: the seed to pass to serde.
pub struct Seed<N>(pub N);

impl<'de, N: Node<'de>> DeserializeSeed<'de> for Seed<N> {
    type Value = N::Out;
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<N::Out, D::Error> {
        d.deserialize_any(Visit(self.0))
    }
}

struct Visit<N>(N);

impl<'de, N: Node<'de>> Visitor<'de> for Visit<N> {
    type Value = N::Out;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, _: bool) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Bool))
    }
    fn visit_i64<E>(self, v: i64) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Num(v as f64, u64::try_from(v).ok())))
    }
    fn visit_u64<E>(self, v: u64) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Num(v as f64, Some(v))))
    }
    fn visit_f64<E>(self, v: f64) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Num(v, None)))
    }
    fn visit_str<E>(self, v: &str) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Str(v.to_owned())))
    }
    fn visit_string<E>(self, v: String) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Str(v)))
    }
    fn visit_unit<E>(self) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Null))
    }
    fn visit_none<E>(self) -> Result<N::Out, E> {
        Ok(self.0.scalar(Scalar::Null))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<N::Out, A::Error> {
        self.0.seq(seq)
    }
    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<N::Out, A::Error> {
        self.0.map(map)
    }
}

/// Reads a scalar as it is (arrays and objects as their kind only).
pub struct Any;

impl Node<'_> for Any {
    type Out = Scalar;
    fn scalar(self, value: Scalar) -> Scalar {
        value
    }
}

/// Reads the elements of an array with a node each, counting them and
/// checking the count against `min..=max`: elements beyond `max` are skipped
/// (not stored), and a wrong count or kind is recorded at `at`.
pub fn elements<'de, A, T>(
    mut seq: A,
    errors: &mut Errors,
    at: Loc<'_>,
    (min, max): (usize, usize),
    mut read: impl FnMut(&mut Errors, usize, &mut A) -> Result<Next<T>, A::Error>,
) -> Result<Option<Vec<T>>, A::Error>
where
    A: SeqAccess<'de>,
{
    let mut out = Vec::new();
    let mut count = 0;
    loop {
        if count < max {
            match read(errors, count, &mut seq)? {
                Some(Some(v)) => out.push(v),
                Some(None) => {}
                None => break,
            }
        } else if seq.next_element::<IgnoredAny>()?.is_none() {
            break;
        }
        count += 1;
    }
    if count < min {
        if count == 0 {
            errors.add(at, "must not be empty");
        } else {
            errors.add(
                at,
                format!("must hold at least {min} elements, not {count}"),
            );
        }
        return Ok(None);
    }
    if count > max {
        errors.add(at, format!("must hold at most {max} elements, not {count}"));
        return Ok(None);
    }
    Ok(Some(out))
}

/// What `read` gives [`elements`]: the next element's reading (`None` at the
/// end of the array; `Some(None)` for an element that was wrong).
pub type Next<T> = Option<Option<T>>;

/// Records `result`'s error at `at`, giving its value otherwise.
pub fn keep<T>(errors: &mut Errors, at: Loc<'_>, result: Result<T, String>) -> Option<T> {
    result.map_err(|why| errors.add(at, why)).ok()
}

/// Reads an object whose members are all scalars, named by `keys`: each
/// member's value in `keys` order (`None` when absent or null). An unknown or
/// repeated key is recorded at it, and then the object gives `None`.
pub fn scalar_fields<'de, A: MapAccess<'de>, const N: usize>(
    mut map: A,
    errors: &mut Errors,
    at: Loc<'_>,
    keys: [&str; N],
) -> Result<Option<[Option<Scalar>; N]>, A::Error> {
    let mut values: [Option<Scalar>; N] = std::array::from_fn(|_| None);
    let mut seen = [false; N];
    let mut ok = true;
    while let Some(key) = map.next_key::<String>()? {
        let here = at.key(&key);
        let Some(k) = keys.iter().position(|x| *x == key) else {
            errors.add(
                here,
                format!(
                    "unknown field `{}`; expected one of: {}",
                    echo(&key),
                    keys.join(", ")
                ),
            );
            map.next_value::<IgnoredAny>()?;
            ok = false;
            continue;
        };
        let v = map.next_value_seed(Seed(Any))?;
        if std::mem::replace(&mut seen[k], true) {
            errors.add(here, format!("duplicate key `{key}`: given more than once"));
            ok = false;
        } else if v != Scalar::Null {
            values[k] = Some(v);
        }
    }
    Ok(ok.then_some(values))
}
