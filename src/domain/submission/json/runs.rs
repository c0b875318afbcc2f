//! `runs`: objects of `readings`, one per position: an array of samples,
//! numbers read straight into `Vec<f64>` with the counts checked as they
//! grow, or a summary object `{"mean", "std", "count"}` from a station that
//! averages on board (its samples are not counted against the limits: they
//! were never sent).

use accelcal_core::{Reading, Summary};
use serde::de::{IgnoredAny, MapAccess, SeqAccess};

use super::super::node::{Any, Node, Scalar, Seed, elements, keep, scalar_fields};
use super::temperature;
use crate::domain::field::{Errors, Loc};
use crate::domain::limits::*;
use crate::domain::text::echo;

use super::super::draft::{RunDraft, Slot};

pub(super) struct Runs<'a> {
    pub(super) errors: &'a mut Errors,
    pub(super) at: Loc<'a>,
}

impl<'de> Node<'de> for Runs<'_> {
    type Out = Slot<Vec<Option<RunDraft>>>;
    fn scalar(self, v: Scalar) -> Self::Out {
        if v == Scalar::Null {
            return Slot::Absent;
        }
        self.errors
            .add(self.at, format!("must be an array, not {}", v.kind()));
        Slot::Invalid
    }
    fn seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Out, A::Error> {
        let at = self.at;
        let mut total = 0usize;
        let read = elements(seq, self.errors, at, (1, MAX_RUNS), |errors, j, seq| {
            let here = at.index(j);
            let node = RunNode {
                errors,
                at: here,
                total: &mut total,
            };
            Ok(seq.next_element_seed(Seed(node))?.map(Some))
        })?;
        if total > MAX_TOTAL_SAMPLES {
            self.errors.add(
                at,
                format!("holds {total} samples in all; at most {MAX_TOTAL_SAMPLES} are accepted"),
            );
            return Ok(Slot::Invalid);
        }
        Ok(Slot::from_read(read))
    }
}

struct RunNode<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
    /// Samples counted so far over all runs; beyond the limit none is kept.
    total: &'a mut usize,
}

impl<'de> Node<'de> for RunNode<'_> {
    type Out = Option<RunDraft>;
    fn scalar(self, v: Scalar) -> Self::Out {
        self.errors
            .add(self.at, format!("must be an object, not {}", v.kind()));
        None
    }
    fn map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Out, A::Error> {
        const KEYS: [&str; 2] = ["readings", "temperature_c"];
        let mut readings = None;
        let mut temperature_c = None;
        let mut each = None;
        let mut seen = [false; 2];
        let mut ok = true;
        while let Some(key) = map.next_key::<String>()? {
            let at = self.at.key(&key);
            let Some(k) = KEYS.iter().position(|x| *x == key) else {
                self.errors.add(
                    at,
                    format!(
                        "unknown field `{}`; expected one of: {}",
                        echo(&key),
                        KEYS.join(", ")
                    ),
                );
                map.next_value::<IgnoredAny>()?;
                ok = false;
                continue;
            };
            if std::mem::replace(&mut seen[k], true) {
                self.errors
                    .add(at, format!("duplicate key `{key}`: given more than once"));
                map.next_value::<IgnoredAny>()?;
                ok = false;
            } else if k == 0 {
                let node = Readings {
                    errors: &mut *self.errors,
                    at,
                    total: &mut *self.total,
                };
                readings = Some(map.next_value_seed(Seed(node))?);
            } else {
                let node = RunTemperature {
                    errors: &mut *self.errors,
                    at,
                };
                match map.next_value_seed(Seed(node))? {
                    Temperatures::Null => {}
                    Temperatures::One(t) => temperature_c = Some(t),
                    Temperatures::Each(ts) => each = Some(ts),
                    Temperatures::Invalid => ok = false,
                }
            }
        }
        // One temperature per position: the run's is their mean.
        if let (Some(ts), Some(Some(r))) = (&each, &readings) {
            if ts.len() == r.len() {
                temperature_c = Some(ts.iter().sum::<f64>() / ts.len() as f64);
            } else {
                self.errors.add(
                    self.at.key("temperature_c"),
                    format!(
                        "must be the run's temperature or one per position ({}), not {}",
                        r.len(),
                        ts.len()
                    ),
                );
                ok = false;
            }
        }
        match readings {
            None => {
                self.errors.add(self.at.key("readings"), "is required");
                Ok(None)
            }
            Some(Some(readings)) if ok => Ok(Some(RunDraft {
                readings,
                temperature_c,
                position_temperatures_c: each,
            })),
            Some(_) => Ok(None),
        }
    }
}

/// A run's `temperature_c` as read.
enum Temperatures {
    /// Absent or `null`.
    Null,
    /// The run's.
    One(f64),
    /// One per position.
    Each(Vec<f64>),
    /// Wrong (recorded).
    Invalid,
}

/// `temperature_c`: the run's, or one per position (a chamber that drifts
/// during the run), each a plausible temperature in °C.
struct RunTemperature<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
}

impl<'de> Node<'de> for RunTemperature<'_> {
    type Out = Temperatures;
    fn scalar(self, v: Scalar) -> Self::Out {
        if v == Scalar::Null {
            return Temperatures::Null;
        }
        match keep(self.errors, self.at, temperature(&v)) {
            Some(t) => Temperatures::One(t),
            None => Temperatures::Invalid,
        }
    }
    fn seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Out, A::Error> {
        let at = self.at;
        let mut wrong = false;
        let read = elements(
            seq,
            self.errors,
            at,
            (1, MAX_POSITIONS),
            |errors, i, seq| {
                Ok(seq.next_element_seed(Seed(Any))?.map(|v| {
                    let t = keep(errors, at.index(i), temperature(&v));
                    wrong |= t.is_none();
                    t
                }))
            },
        )?;
        Ok(match read {
            Some(ts) if !wrong => Temperatures::Each(ts),
            _ => Temperatures::Invalid,
        })
    }
}

/// `readings`: per position, its samples or their summary.
struct Readings<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
    total: &'a mut usize,
}

impl<'de> Node<'de> for Readings<'_> {
    type Out = Option<Vec<Reading>>;
    fn scalar(self, v: Scalar) -> Self::Out {
        let why = match v {
            Scalar::Null => "is required".to_owned(),
            v => format!("must be an array, not {}", v.kind()),
        };
        self.errors.add(self.at, why);
        None
    }
    fn seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Out, A::Error> {
        let at = self.at;
        let total = self.total;
        let mut ok = true;
        let read = elements(
            seq,
            self.errors,
            at,
            (1, MAX_POSITIONS),
            |errors, i, seq| {
                let node = Samples {
                    errors,
                    at: at.index(i),
                    total: &mut *total,
                };
                let got = seq.next_element_seed(Seed(node))?;
                ok &= !matches!(got, Some(None));
                Ok(got.map(|s| s.map(Some).unwrap_or(None)))
            },
        )?;
        Ok(read.filter(|_| ok))
    }
}

/// The reading of one position in one run: samples or a summary.
/// The members of a summary reading.
pub const SUMMARY_KEYS: [&str; 3] = ["mean", "std", "count"];

struct Samples<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
    total: &'a mut usize,
}

impl<'de> Node<'de> for Samples<'_> {
    type Out = Option<Reading>;
    fn scalar(self, v: Scalar) -> Self::Out {
        self.errors.add(
            self.at,
            format!(
                "must be an array of samples or an object of `mean`, `std` and `count`, not {}",
                v.kind()
            ),
        );
        None
    }
    fn map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Out, A::Error> {
        let (errors, at) = (self.errors, self.at);
        let Some([mean, std, count]) = scalar_fields(map, errors, at, SUMMARY_KEYS)? else {
            return Ok(None);
        };
        let mut field =
            |k: usize, v: Option<Scalar>, read: &dyn Fn(Scalar) -> Result<f64, String>| {
                let here = at.key(SUMMARY_KEYS[k]);
                match v {
                    None => {
                        errors.add(here, "is required");
                        None
                    }
                    Some(v) => keep(errors, here, read(v)),
                }
            };
        let mean = field(0, mean, &|v| v.number(MAX_READING));
        let std = field(1, std, &|v| {
            v.number(MAX_READING).and_then(|s| {
                if s < 0.0 {
                    Err("must not be negative".into())
                } else {
                    Ok(s)
                }
            })
        });
        let count = field(2, count, &|v| {
            v.integer(1, MAX_SUMMARY_COUNT).map(|n| n as f64)
        });
        let (Some(mean), Some(std), Some(count)) = (mean, std, count) else {
            return Ok(None);
        };
        if count == 1.0 && std != 0.0 {
            errors.add(
                at.key("std"),
                "must be 0 when `count` is 1: one sample has no spread",
            );
            return Ok(None);
        }
        Ok(Some(Reading::Summary(Summary {
            mean,
            std,
            count: count as u64,
        })))
    }
    fn seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Out, A::Error> {
        let at = self.at;
        let total = self.total;
        let mut ok = true;
        let read = elements(seq, self.errors, at, (1, MAX_SAMPLES), |errors, s, seq| {
            let Some(v) = seq.next_element_seed(Seed(Any))? else {
                return Ok(None);
            };
            *total += 1;
            let x = keep(errors, at.index(s), v.number(MAX_READING));
            ok &= x.is_some();
            // Beyond the total limit nothing more is kept (it is refused).
            Ok(Some(x.filter(|_| *total <= MAX_TOTAL_SAMPLES)))
        })?;
        Ok(read.filter(|_| ok).map(Reading::Samples))
    }
}
