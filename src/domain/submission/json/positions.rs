//! `positions`: objects of `angle_deg`, `a` and `label`.

use accelcal_core::Gravity;
use serde::de::{IgnoredAny, MapAccess, SeqAccess};

use super::super::node::{Any, Node, Scalar, Seed, elements, keep};
use crate::domain::field::{Errors, Loc};
use crate::domain::limits::*;
use crate::domain::text::{Chars, echo};

use super::super::draft::{PositionDraft, Slot};
use super::gravity;

pub(super) struct Positions<'a> {
    pub(super) errors: &'a mut Errors,
    pub(super) at: Loc<'a>,
}

impl<'de> Node<'de> for Positions<'_> {
    type Out = Slot<Vec<Option<PositionDraft>>>;
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
        let read = elements(
            seq,
            self.errors,
            at,
            (1, MAX_POSITIONS),
            |errors, k, seq| {
                let here = at.index(k);
                Ok(seq
                    .next_element_seed(Seed(PositionNode { errors, at: here }))?
                    .map(Some))
            },
        )?;
        Ok(Slot::from_read(read))
    }
}

struct PositionNode<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
}

impl<'de> Node<'de> for PositionNode<'_> {
    type Out = Option<PositionDraft>;
    fn scalar(self, v: Scalar) -> Self::Out {
        self.errors
            .add(self.at, format!("must be an object, not {}", v.kind()));
        None
    }
    fn map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Out, A::Error> {
        const KEYS: [&str; 3] = ["angle_deg", "a", "label"];
        let mut p = PositionDraft::default();
        let mut ok = true;
        let mut seen = [false; 3];
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
                continue;
            }
            let read = match k {
                0 => {
                    let v = map.next_value_seed(Seed(Any))?;
                    (v != Scalar::Null).then(|| {
                        keep(self.errors, at, v.number(MAX_ANGLE_DEG))
                            .map(|x| p.angle_deg = Some(x))
                    })
                }
                1 => {
                    let a = map.next_value_seed(Seed(Components {
                        errors: &mut *self.errors,
                        at,
                    }))?;
                    a.map(|a| a.map(|a| p.a = Some(a)))
                }
                _ => {
                    let v = map.next_value_seed(Seed(Any))?;
                    (v != Scalar::Null).then(|| {
                        keep(self.errors, at, v.string(MAX_LABEL_CHARS, Chars::Text))
                            .map(|l| p.label = Some(l))
                    })
                }
            };
            ok &= !matches!(read, Some(None));
        }
        Ok(ok.then_some(p))
    }
}

/// `a`: three numbers with a norm near 1 g. `None` for `null`; `Some(None)`
/// when wrong (recorded).
struct Components<'a> {
    errors: &'a mut Errors,
    at: Loc<'a>,
}

impl<'de> Node<'de> for Components<'_> {
    type Out = Option<Option<Gravity>>;
    fn scalar(self, v: Scalar) -> Self::Out {
        if v == Scalar::Null {
            return None;
        }
        self.errors
            .add(self.at, format!("must be an array, not {}", v.kind()));
        Some(None)
    }
    fn seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Out, A::Error> {
        let at = self.at;
        let read = elements(seq, self.errors, at, (3, 3), |errors, k, seq| {
            let Some(v) = seq.next_element_seed(Seed(Any))? else {
                return Ok(None);
            };
            Ok(Some(keep(
                errors,
                at.index(k),
                v.number(MAX_GRAVITY_COMPONENT),
            )))
        })?;
        // A wrong component is recorded and left out: three read means
        // three good.
        let Some(xs) = read.filter(|xs| xs.len() == 3) else {
            return Ok(Some(None));
        };
        Ok(Some(keep(self.errors, at, gravity([xs[0], xs[1], xs[2]]))))
    }
}
